#include "deep_ois/tools/support/correspondence_proposer.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

namespace deep_ois {

namespace {

// Normalised cross-correlation of two equally sized float patches; 0 for a flat patch.
double zncc(const cv::Mat& a, const cv::Mat& b) {
  cv::Scalar mean_a, std_a, mean_b, std_b;
  cv::meanStdDev(a, mean_a, std_a);
  cv::meanStdDev(b, mean_b, std_b);
  if (std_a[0] <= 0.0 || std_b[0] <= 0.0) return 0.0;
  cv::Mat da = a - mean_a[0], db = b - mean_b[0];
  return da.dot(db) / (static_cast<double>(a.total()) * std_a[0] * std_b[0]);
}

// Vertex of the parabola through (-1, l), (0, c), (1, r): the sub-sample offset of a peak.
double parabolaPeak(double l, double c, double r) {
  const double denominator = l - 2.0 * c + r;
  return std::abs(denominator) < 1e-12 ? 0.0 : std::clamp(0.5 * (l - r) / denominator, -0.5, 0.5);
}

cv::Mat patchAt(const cv::Mat& gray_float, const cv::Point2d& centre, int half_px) {
  cv::Mat patch;
  cv::getRectSubPix(gray_float, cv::Size(2 * half_px + 1, 2 * half_px + 1),
                    cv::Point2f(static_cast<float>(centre.x), static_cast<float>(centre.y)), patch);
  return patch;
}

// Where the template of frame a around `point_a` lies in frame b near `guess_b`: both upsampled
// `zoom` times, TM_CCOEFF_NORMED, the peak refined by a parabola per axis. Equal resampling of
// template and search area keeps a shift of d source pixels at d * zoom zoomed pixels.
cv::Point2d matchZoomedTemplate(const cv::Mat& a, const cv::Mat& b, const cv::Point2d& point_a,
                                const cv::Point2d& guess_b, const CorrespondenceProposerOptions& o) {
  const cv::Mat templ_small = patchAt(a, point_a, o.template_half_px);
  const cv::Mat search_small = patchAt(b, guess_b, o.template_half_px + o.search_half_px);
  cv::Mat templ, search, score;
  cv::resize(templ_small, templ, cv::Size(), o.zoom, o.zoom, cv::INTER_CUBIC);
  cv::resize(search_small, search, cv::Size(), o.zoom, o.zoom, cv::INTER_CUBIC);
  cv::matchTemplate(search, templ, score, cv::TM_CCOEFF_NORMED);
  cv::Point peak;
  cv::minMaxLoc(score, nullptr, nullptr, nullptr, &peak);
  double dx = peak.x, dy = peak.y;
  if (peak.x > 0 && peak.x < score.cols - 1) {
    dx += parabolaPeak(score.at<float>(peak.y, peak.x - 1), score.at<float>(peak.y, peak.x),
                       score.at<float>(peak.y, peak.x + 1));
  }
  if (peak.y > 0 && peak.y < score.rows - 1) {
    dy += parabolaPeak(score.at<float>(peak.y - 1, peak.x), score.at<float>(peak.y, peak.x),
                       score.at<float>(peak.y + 1, peak.x));
  }
  // The search area is (template + 2 search) wide: a zero shift puts the peak at search * zoom.
  const double centre = static_cast<double>(o.search_half_px) * o.zoom;
  return guess_b + cv::Point2d((dx - centre) / o.zoom, (dy - centre) / o.zoom);
}

}  // namespace

std::string CorrespondenceProposerOptions::validate() const {
  std::ostringstream why;
  if (max_candidates < 1) why << "max_candidates must be >= 1";
  else if (!(min_distance_px >= 1.0)) why << "min_distance_px must be >= 1";
  else if (!(corner_quality > 0.0 && corner_quality < 1.0)) why << "corner_quality must be in (0, 1)";
  else if (corner_block_px < 3) why << "corner_block_px must be >= 3";
  else if (subpixel_half_window_px < 1) why << "subpixel_half_window_px must be >= 1";
  else if (template_half_px < 2) why << "template_half_px must be >= 2";
  else if (search_half_px < 1) why << "search_half_px must be >= 1";
  else if (zoom < 1 || zoom > 16) why << "zoom must be in [1, 16]";
  else if (!(min_zncc > -1.0 && min_zncc <= 1.0)) why << "min_zncc must be in (-1, 1]";
  else if (!(max_disagreement_px > 0.0)) why << "max_disagreement_px must be > 0";
  else {
    const std::string klt_problem = klt.validate();
    if (!klt_problem.empty()) why << "klt: " << klt_problem;
  }
  return why.str();
}

std::vector<CorrespondenceCandidate> proposeCorrespondences(const cv::Mat& gray_a, const cv::Mat& gray_b,
                                                            const cv::Rect& region,
                                                            const CorrespondenceProposerOptions& options) {
  const std::string problem = options.validate();
  if (!problem.empty()) throw std::invalid_argument("correspondence proposer: " + problem);
  if (gray_a.type() != CV_8UC1 || gray_b.type() != CV_8UC1 || gray_a.size() != gray_b.size()) {
    throw std::invalid_argument("correspondence proposer: frames must be CV_8UC1 of one size");
  }
  const cv::Rect clipped = region & cv::Rect(0, 0, gray_a.cols, gray_a.rows);
  if (clipped.area() == 0) throw std::invalid_argument("correspondence proposer: the region is outside the image");

  // Shi-Tomasi corners of the region, refined to sub-pixel accuracy in frame a.
  cv::Mat mask = cv::Mat::zeros(gray_a.size(), CV_8UC1);
  mask(clipped).setTo(255);
  std::vector<cv::Point2f> corners;
  cv::goodFeaturesToTrack(gray_a, corners, 20 * options.max_candidates, options.corner_quality,
                          options.min_distance_px, mask, options.corner_block_px);
  if (corners.empty()) return {};
  const cv::TermCriteria criteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 40, 0.001);
  cv::cornerSubPix(gray_a, corners,
                   cv::Size(options.subpixel_half_window_px, options.subpixel_half_window_px),
                   cv::Size(-1, -1), criteria);
  cv::Mat strength;
  cv::cornerMinEigenVal(gray_a, strength, options.corner_block_px);

  std::vector<TrackStatus> status;
  const std::vector<FeatureMatch> matches = trackFeatures(gray_a, gray_b, corners, options.klt, &status);
  cv::Mat a_float, b_float;
  gray_a.convertTo(a_float, CV_32F);
  gray_b.convertTo(b_float, CV_32F);
  std::vector<CorrespondenceCandidate> candidates;
  for (const FeatureMatch& match : matches) {
    CorrespondenceCandidate c;
    c.point_a_px = match.point_a_px;
    c.klt_point_b_px = match.point_b_px;
    c.forward_backward_error_px = match.forward_backward_error_px;
    // The templates must stay inside both images.
    const double reach = options.template_half_px + options.search_half_px + 2.0;
    auto inside = [&](const cv::Point2d& p) {
      return p.x >= reach && p.y >= reach && p.x <= gray_a.cols - 1 - reach && p.y <= gray_a.rows - 1 - reach;
    };
    if (!inside(c.point_a_px) || !inside(c.klt_point_b_px)) continue;
    c.point_b_px = matchZoomedTemplate(a_float, b_float, c.point_a_px, c.klt_point_b_px, options);
    c.disagreement_px = cv::norm(c.point_b_px - c.klt_point_b_px);
    if (!(c.disagreement_px <= options.max_disagreement_px)) continue;
    c.zncc = zncc(patchAt(a_float, c.point_a_px, options.template_half_px),
                  patchAt(b_float, c.point_b_px, options.template_half_px));
    if (!(c.zncc >= options.min_zncc)) continue;
    const cv::Point corner(static_cast<int>(std::lround(c.point_a_px.x)), static_cast<int>(std::lround(c.point_a_px.y)));
    c.corner_strength = strength.at<float>(corner);
    candidates.push_back(c);
  }
  std::stable_sort(candidates.begin(), candidates.end(),
                   [](const CorrespondenceCandidate& x, const CorrespondenceCandidate& y) {
                     return x.corner_strength > y.corner_strength;
                   });
  if (static_cast<int>(candidates.size()) > options.max_candidates) candidates.resize(options.max_candidates);
  for (std::size_t i = 0; i < candidates.size(); ++i) candidates[i].id = static_cast<int>(i);
  return candidates;
}

namespace {

// The (2 half + 1)^2 pixels around the pixel nearest `point`, upsampled by nearest neighbour,
// with a cross on the sub-pixel point.
cv::Mat zoomedCrop(const cv::Mat& rgb, const cv::Point2d& point, int half_px, int zoom, const cv::Scalar& colour) {
  const cv::Point2f centre(static_cast<float>(std::round(point.x)), static_cast<float>(std::round(point.y)));
  cv::Mat crop, zoomed;
  cv::getRectSubPix(rgb, cv::Size(2 * half_px + 1, 2 * half_px + 1), centre, crop);  // integer centre: exact
  cv::resize(crop, zoomed, cv::Size(), zoom, zoom, cv::INTER_NEAREST);
  // Source pixel i covers zoomed [i zoom, (i + 1) zoom): its centre is at (i + 0.5) zoom - 0.5.
  const double x = (point.x - (centre.x - half_px) + 0.5) * zoom - 0.5;
  const double y = (point.y - (centre.y - half_px) + 0.5) * zoom - 0.5;
  constexpr int kShift = 4;  // sub-pixel drawing: coordinates in 1/16 pixel
  auto fixed = [](double v) { return static_cast<int>(std::lround(v * (1 << kShift))); };
  const int arm = 3 * zoom;
  cv::line(zoomed, cv::Point(fixed(x - arm), fixed(y)), cv::Point(fixed(x - zoom / 2.0), fixed(y)), colour, 1,
           cv::LINE_AA, kShift);
  cv::line(zoomed, cv::Point(fixed(x + zoom / 2.0), fixed(y)), cv::Point(fixed(x + arm), fixed(y)), colour, 1,
           cv::LINE_AA, kShift);
  cv::line(zoomed, cv::Point(fixed(x), fixed(y - arm)), cv::Point(fixed(x), fixed(y - zoom / 2.0)), colour, 1,
           cv::LINE_AA, kShift);
  cv::line(zoomed, cv::Point(fixed(x), fixed(y + zoom / 2.0)), cv::Point(fixed(x), fixed(y + arm)), colour, 1,
           cv::LINE_AA, kShift);
  return zoomed;
}

}  // namespace

cv::Mat renderCandidateCrop(const cv::Mat& rgb_a, const cv::Mat& rgb_b, const CorrespondenceCandidate& candidate,
                            int half_px, int zoom) {
  const cv::Scalar green(0, 255, 0);
  const cv::Mat left = zoomedCrop(rgb_a, candidate.point_a_px, half_px, zoom, green);
  const cv::Mat right = zoomedCrop(rgb_b, candidate.point_b_px, half_px, zoom, green);
  cv::Mat gap(left.rows, 6, left.type(), cv::Scalar::all(255));
  cv::Mat sheet;
  cv::hconcat(std::vector<cv::Mat>{left, gap, right}, sheet);
  return sheet;
}

cv::Mat renderCandidateOverview(const cv::Mat& rgb_a, const cv::Rect& region,
                                const std::vector<CorrespondenceCandidate>& candidates) {
  cv::Mat overview = rgb_a.clone();
  const cv::Scalar white(255, 255, 255), green(0, 255, 0);  // the same in RGB and BGR order
  cv::rectangle(overview, region, white, 1);
  for (const CorrespondenceCandidate& c : candidates) {
    const cv::Point p(static_cast<int>(std::lround(c.point_a_px.x)), static_cast<int>(std::lround(c.point_a_px.y)));
    cv::circle(overview, p, 4, green, 1, cv::LINE_AA);
    cv::putText(overview, std::to_string(c.id), p + cv::Point(5, -5), cv::FONT_HERSHEY_SIMPLEX, 0.45, green, 1,
                cv::LINE_AA);
  }
  return overview;
}

}  // namespace deep_ois
