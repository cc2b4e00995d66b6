// A camera's own log of its OIS lens position: time-stamped samples of the lens shift, as a phone
// reports them (Android camera2 OisSample: a timestamp on the sensor clock and the x, y shift in
// pixels of the sensor's active array) or a module's Hall sensor. Pure core: no ROS.
//
// Why a class and not a vector: a log is only usable where it is dense. A gap (dropped samples, a
// paused stream) longer than max_gap_s is not bridged by interpolation: the lens moves several
// pixels in 20 ms, so a straight line across a gap would be a wrong motion, not a rough one.
// Callers ask covers(t0, t1) and fall back (to the network) where it is false.
//
// Units: stamps in seconds; shifts in pixels of the image the camera publishes, after the
// per-camera convention maps the logged numbers to them (LensShiftLogConvention).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <deque>
#include <optional>
#include <string>

namespace deep_ois {

// How a camera's logged numbers map to the lens shift of the published image. The lens shift s is
// what the principal point moves by: the OIS camera's intrinsics at time t are K with
// (cx, cy) + s(t) (x right, y down, pixels of the published image).
//
//   s = scale * P * (logged x, logged y),   P = [sign_x 0; 0 sign_y] * (swap_xy ? [0 1; 1 0] : I)
//   camera-clock time = logged stamp + time_offset_s
//
// Examples: a log in active-array pixels of a 4000 px wide sensor and a published 1920 px wide
// image: scale = 1920 / 4000 = 0.48. A log of the lens' own displacement rather than the image's
// (or a sensor mounted upside down): sign_x = sign_y = -1. A log on the sensor's native
// (landscape) axes and a portrait stream: swap_xy = true plus a sign.
struct LensShiftLogConvention {
  double scale = 1.0;    // published-image pixels per logged unit (> 0)
  bool swap_xy = false;  // the logged x is the image's y and vice versa (applied before signs)
  double sign_x = 1.0;   // +1 or -1, on the image x after the swap
  double sign_y = 1.0;   // +1 or -1, on the image y after the swap
  double time_offset_s = 0.0;  // added to logged stamps to get camera-clock seconds

  // The 2x2 matrix scale * P above.
  Eigen::Matrix2d matrix() const;
  // Logged numbers -> published-image pixels.
  Eigen::Vector2d toImagePx(const Eigen::Vector2d& logged) const;
  // Empty when usable; otherwise a sentence naming the bad field.
  std::string validate() const;
};

// One logged sample, as the camera gave it (the convention is applied on query).
struct LensShiftLogSample {
  double stamp_s = 0.0;    // logged stamp, seconds (the log's clock)
  Eigen::Vector2d logged;  // logged x, y (the log's units)
  // Covariance of `logged`, the log's units squared; empty when the camera does not say.
  std::optional<Eigen::Matrix2d> covariance;
};

// Why add() refused a sample; empty `reason` when accepted.
struct LensShiftAddResult {
  std::string reason;
  bool accepted() const { return reason.empty(); }
};

class LensShiftLog {
 public:
  // max_gap_s: consecutive samples further apart than this are a gap (not covered). A 200 Hz
  // log has 5 ms between samples; the default tolerates two lost samples in a row.
  // Throws std::invalid_argument when max_gap_s is not positive or the convention is invalid.
  explicit LensShiftLog(double max_gap_s = 0.02, const LensShiftLogConvention& convention = {});

  // Appends a sample. Refuses (and keeps nothing of) a non-finite sample or one whose stamp is not
  // after the newest: a log is in time order, and a repeated stamp is a duplicate.
  LensShiftAddResult add(const LensShiftLogSample& sample);

  // True when [t0_s, t1_s] (camera clock, t0 <= t1) lies between two samples and no two
  // consecutive samples inside or around it are further apart than max_gap_s.
  bool covers(double t0_s, double t1_s) const;

  // The lens shift at camera-clock time t_s, published-image pixels: linear between the two
  // samples around t. Throws std::out_of_range unless covers(t_s, t_s).
  Eigen::Vector2d shiftAt(double t_s) const;

  // The newest sample's camera-clock stamp; -infinity when empty.
  double newestStampS() const;
  // The oldest sample's camera-clock stamp; +infinity when empty.
  double oldestStampS() const;
  // Forgets samples older than t_s (camera clock), keeping the one just before it so that
  // covers(t_s, ...) stays answerable. For a live stream's bounded memory.
  void dropBefore(double t_s);
  void clear() { samples_.clear(); }
  std::size_t size() const { return samples_.size(); }
  bool empty() const { return samples_.empty(); }
  const std::deque<LensShiftLogSample>& samples() const { return samples_; }

  const LensShiftLogConvention& convention() const { return convention_; }
  // Throws std::invalid_argument when invalid. Samples stay (they are kept as logged).
  void setConvention(const LensShiftLogConvention& convention);
  double maxGapS() const { return max_gap_s_; }

 private:
  // Index of the last sample whose camera-clock stamp is <= t_s; -1 when none.
  std::ptrdiff_t lastAtOrBefore(double t_s) const;
  double cameraTime(const LensShiftLogSample& s) const {
    return s.stamp_s + convention_.time_offset_s;
  }

  double max_gap_s_;
  LensShiftLogConvention convention_;
  std::deque<LensShiftLogSample> samples_;
};

}  // namespace deep_ois
