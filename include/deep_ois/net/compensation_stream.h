// A compensation model run over the consecutive frame pairs of one camera: it keeps the motion
// history the model takes beside each pair's gyro flow (core/flow/motion_history.h). The compensation
// nodelet, the evaluator (one per recording) and the benchmark all go through it, so live and
// offline results are the same computation.
#pragma once

#include <cstdint>

#include <opencv2/core.hpp>

#include "deep_ois/core/flow/motion_history.h"
#include "deep_ois/net/compensation_model.h"

namespace deep_ois {

class CompensationStream {
 public:
  // Keeps a reference: `model` must outlive the stream.
  explicit CompensationStream(const CompensationModel& model);

  // The compensated flow of pair a -> b (frame stamps in nanoseconds; pairs in time order). The
  // gyro flow is CV_32FC2 on any grid, the result on the same grid. A pair that does not start
  // where the previous one ended (a dropped frame, a loop) restarts the history from zero, as at
  // the start of a stream.
  cv::Mat compensate(const cv::Mat& gyro_flow, std::int64_t stamp_a_ns, std::int64_t stamp_b_ns);

  // Adds pair a -> b to the history without running the network: a pair whose output nobody can
  // use (its frames never came) still moved the camera.
  void observe(const cv::Mat& gyro_flow, std::int64_t stamp_a_ns, std::int64_t stamp_b_ns);

  void reset() { history_.reset(); }
  const MotionHistory& history() const { return history_; }

 private:
  const CompensationModel& model_;
  MotionHistory history_;
};

}  // namespace deep_ois
