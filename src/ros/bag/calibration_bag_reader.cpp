#include "deep_ois/ros/bag/calibration_bag_reader.h"

#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <chrono>
#include <stdexcept>
#include <utility>

#include "deep_ois/ros/bag/bag_frame_reader.h"

namespace deep_ois {


CalibrationBag readCalibrationBag(const std::string& path, const CalibrationBagOptions& options,
                                  const ProgressCallback& on_progress) {
  const BagSequence sequence = readBagSequence(path, options.topics);
  // Before tracking (the slow part): without IMU messages there is nothing to calibrate against.
  if (!sequence.imu_problem.empty()) throw std::runtime_error(path + ": " + sequence.imu_problem);
  CalibrationBag out;
  out.tf_problem = sequence.imu_to_camera_problem;
  out.data.gyro = sequence.imu_samples;
  out.data.camera = *sequence.camera;
  out.imu_frame_id = sequence.imu_frame_id;
  out.camera_frame_id = sequence.camera_frame_id;
  out.tf_imu_to_camera_rotation = sequence.imu_to_camera_rotation;
  if (!sequence.truths.empty()) out.simulated_ois_enabled = sequence.truths.front().ois_enabled;
  out.lens_shift_log = sequence.lens_shift_log;

  const FeatureTracker tracker(options.corners, options.klt);
  const cv::Size camera_size(out.data.camera.width(), out.data.camera.height());
  BagFrameReader reader(path, options.topics.image);
  const std::size_t pair_total = on_progress ? indexedFramePairCount(path, options.topics.image) : 0;
  BagFrame previous, current;
  double tracking_s = 0.0;
  auto checkSize = [&](const BagFrame& frame) {
    if (frame.gray.size() != camera_size) {
      throw std::runtime_error(path + ": frame " + std::to_string(reader.framesRead()) + " on " +
                               options.topics.image + " is " + std::to_string(frame.gray.cols) + "x" +
                               std::to_string(frame.gray.rows) + " but camera_info says " +
                               std::to_string(camera_size.width) + "x" + std::to_string(camera_size.height));
    }
  };
  if (!reader.next(previous)) throw std::runtime_error(path + ": no frame on " + options.topics.image);
  checkSize(previous);
  out.data.frame_stamps_s.push_back(sequence.secondsSinceBase(previous.stamp));
  while (reader.next(current)) {
    checkSize(current);
    const double stamp_s = sequence.secondsSinceBase(current.stamp);
    const double interval_s = stamp_s - out.data.frame_stamps_s.back();
    if (!(interval_s > 0.0)) {
      throw std::runtime_error(path + ": frame " + std::to_string(reader.framesRead()) + " on " +
                               options.topics.image + " does not come after the previous one (stamp " +
                               std::to_string(interval_s) + " s apart)");
    }
    out.data.frame_stamps_s.push_back(stamp_s);
    const int b = static_cast<int>(out.data.frame_stamps_s.size()) - 1;
    if (interval_s <= options.max_frame_interval_s) {
      const auto started = std::chrono::steady_clock::now();
      CalibrationPair pair;
      pair.frame_a = b - 1;
      pair.frame_b = b;
      pair.matches = tracker.match(previous.gray, current.gray);
      tracking_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
      out.data.pairs.push_back(std::move(pair));
    }
    if (on_progress) on_progress(static_cast<std::size_t>(b), pair_total);
    std::swap(previous, current);
  }
  if (out.data.frame_stamps_s.size() < 2) throw std::runtime_error(path + ": fewer than two frames on " + options.topics.image);
  out.frames = out.data.frame_stamps_s.size();
  out.tracking_seconds = tracking_s;
  return out;
}

}  // namespace deep_ois
