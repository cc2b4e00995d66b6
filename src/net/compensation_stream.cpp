#include "deep_ois/net/compensation_stream.h"

#include <stdexcept>

#include "deep_ois/core/flow/flow_resample.h"

namespace deep_ois {

CompensationStream::CompensationStream(const CompensationModel& model)
    : model_(model), history_(model.metadata().history_time_constants_s, model.metadata().working_grid) {}

void CompensationStream::observe(const cv::Mat& gyro_flow, std::int64_t stamp_a_ns, std::int64_t stamp_b_ns) {
  if (history_.timeConstantsS().empty()) return;
  // The sums grow from the gyro flows on the working grid, as the trainer renders them.
  history_.add(stamp_a_ns, stamp_b_ns, resampleFlow(gyro_flow, model_.metadata().working_grid));
}

cv::Mat CompensationStream::compensate(const cv::Mat& gyro_flow, std::int64_t stamp_a_ns, std::int64_t stamp_b_ns) {
  if (stamp_b_ns <= stamp_a_ns) throw std::invalid_argument("compensate: frame b must come after frame a");
  cv::Mat compensated = model_.compensate(gyro_flow, history_.before(stamp_a_ns));
  observe(gyro_flow, stamp_a_ns, stamp_b_ns);  // the pair joins the history of the next ones
  return compensated;
}

}  // namespace deep_ois
