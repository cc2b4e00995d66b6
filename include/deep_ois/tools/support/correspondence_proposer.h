// Proposes point correspondences between two frames for hand-verified annotation files (real
// recordings have no ground truth): strong corners in a region chosen by a person, refined and
// tracked with independent checks, and zoomed crops on which a person accepts or rejects each
// one. Pure OpenCV: no ROS.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "deep_ois/core/vision/feature_tracker.h"

namespace deep_ois {

struct CorrespondenceProposerOptions {
  int max_candidates = 12;            // per pair, strongest corners first
  // Between two detected corners of a pair; cornerSubPix may then move each by up to
  // subpixel_half_window_px per axis.
  double min_distance_px = 25.0;
  double corner_quality = 0.02;       // Shi-Tomasi threshold, relative to the region's best corner
  int corner_block_px = 7;            // Shi-Tomasi gradient window
  int subpixel_half_window_px = 4;    // cornerSubPix window (2 n + 1 pixels) in frame a
  KltOptions klt = strictKlt();       // a -> b tracking with its forward-backward check
  int template_half_px = 7;           // template (2 n + 1 pixels) around the point of frame a
  int search_half_px = 3;             // template search around KLT's point in frame b, pixels
  int zoom = 4;                       // upsampling (bicubic) of template and search area
  double min_zncc = 0.95;             // normalised cross-correlation of the final patches
  double max_disagreement_px = 0.3;   // |KLT point - template-matching point| in frame b

  static KltOptions strictKlt() {
    KltOptions klt;
    klt.max_forward_backward_error_px = 0.1;
    klt.image_margin_px = 20.0;
    return klt;
  }
  // Empty when usable; otherwise a sentence naming the bad field.
  std::string validate() const;
};

struct CorrespondenceCandidate {
  int id = 0;                  // rank in the pair: 0 = strongest corner that passed every check
  cv::Point2d point_a_px;      // corner in frame a, sub-pixel (cornerSubPix)
  cv::Point2d point_b_px;      // the same point in frame b: zoomed template matching
  cv::Point2d klt_point_b_px;  // frame b by KLT, the independent estimate
  double corner_strength = 0;  // Shi-Tomasi minimum eigenvalue at the corner
  double forward_backward_error_px = 0;
  double disagreement_px = 0;  // |point_b_px - klt_point_b_px|
  double zncc = 0;             // of the (2 template_half_px + 1)^2 patches at point_a and point_b
};

// Candidates in `region` of frame a (pixels; clipped to the image) that pass every check, at most
// max_candidates, strongest first. `gray_a`, `gray_b`: CV_8UC1 of one size. Throws
// std::invalid_argument on bad input or options.
std::vector<CorrespondenceCandidate> proposeCorrespondences(const cv::Mat& gray_a, const cv::Mat& gray_b,
                                                            const cv::Rect& region,
                                                            const CorrespondenceProposerOptions& options);

// A crop for visual verification: the (2 half_px + 1)^2 neighbourhood of the point in frame a
// and in frame b side by side, each upsampled `zoom` times (nearest neighbour, so pixels stay
// visible), with a cross on the sub-pixel point. `rgb_*`: CV_8UC3 (any channel order; returned
// in the same order).
cv::Mat renderCandidateCrop(const cv::Mat& rgb_a, const cv::Mat& rgb_b, const CorrespondenceCandidate& candidate,
                            int half_px = 12, int zoom = 8);

// Frame a with the region and every candidate numbered by its id, for choosing among them.
cv::Mat renderCandidateOverview(const cv::Mat& rgb_a, const cv::Rect& region,
                                const std::vector<CorrespondenceCandidate>& candidates);

}  // namespace deep_ois
