#include "deep_ois/tools/support/simulation_bag_writer.h"

#include <cv_bridge/cv_bridge.h>
#include <deep_ois/FramePairTruth.h>
#include <deep_ois/LensShift.h>
#include <deep_ois/LensShiftSample.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/distortion_models.h>
#include <sensor_msgs/image_encodings.h>

#include <algorithm>
#include <cmath>

#include "deep_ois/ros/messages/conversions.h"
#include "deep_ois/ros/messages/recording_bag_messages.h"

namespace deep_ois {

namespace {

// One message to write, ordered by bag time.
struct Pending {
  ros::Time time;
  std::function<void()> write;
};

}  // namespace

SimulationBagStats writeSimulationBag(const sim::Simulator& simulator, const std::string& path,
                                      rosbag::compression::CompressionType compression,
                                      const SimulationBagTopics& topics,
                                      const std::function<void(int, int)>& progress,
                                      const std::atomic<bool>* stop) {
  const sim::SimulatorConfig& config = simulator.config();
  const sim::SensorConfig& sensor = config.sensor;
  const CameraModel& camera = simulator.camera().nominal();
  const double epoch = config.start_epoch_s;
  SimulationBagStats stats;

  rosbag::Bag bag;
  bag.open(path, rosbag::bagmode::Write);
  bag.setCompression(compression);

  // Static transform, latched like a tf_static publisher, at the time of the first message.
  const ros::Time first_time = toRosTime(epoch, std::min(simulator.imu().front().stamp_s, -0.1));
  writeLatched(bag, topics.tf_static, first_time,
               makeImuToCameraTransform(first_time, config.imu_frame_id, config.camera_frame_id,
                                        config.imu.imu_to_camera_rotation),
               "/deep_ois_simulator");

  // IMU and lens-shift streams, merged with the frames in time order.
  std::vector<Pending> stream;
  const double gyro_sigma = config.imu.gyro_noise_density * std::sqrt(config.imu.rate_hz / 2.0);
  const double accel_sigma = config.imu.accel_noise_density * std::sqrt(config.imu.rate_hz / 2.0);
  for (const sim::ImuMeasurement& m : simulator.imu()) {
    sensor_msgs::Imu imu = makeGyroImuMessage(toRosTime(epoch, m.stamp_s), config.imu_frame_id,
                                              m.angular_velocity_rad_s, gyro_sigma * gyro_sigma);
    imu.linear_acceleration.x = m.linear_acceleration_m_s2.x();
    imu.linear_acceleration.y = m.linear_acceleration_m_s2.y();
    imu.linear_acceleration.z = m.linear_acceleration_m_s2.z();
    for (int i = 0; i < 3; ++i) imu.linear_acceleration_covariance[4 * i] = accel_sigma * accel_sigma;
    stream.push_back({imu.header.stamp, [&bag, &topics, &stats, imu] {
                        bag.write(topics.imu, imu.header.stamp, imu);
                        ++stats.imu_messages;
                      }});
  }
  for (const sim::LensShiftSample& s : simulator.lensShiftSamples()) {
    LensShift shift;
    shift.header.stamp = toRosTime(epoch, s.stamp_s);
    shift.header.frame_id = config.camera_frame_id;
    shift.shift_x = s.shift_px.x();
    shift.shift_y = s.shift_px.y();
    stream.push_back({shift.header.stamp, [&bag, &topics, &stats, shift] {
                        bag.write(topics.lens_shift, shift.header.stamp, shift);
                        ++stats.lens_shift_messages;
                      }});
  }
  // The camera's lens log: header stamp on the log's clock, bag time when it was delivered.
  for (const sim::LoggedLensSample& logged : simulator.lensShiftLog()) {
    LensShiftSample sample;
    sample.header.stamp = toRosTime(epoch, logged.sample.stamp_s);
    sample.header.frame_id = config.camera_frame_id;
    sample.x = logged.sample.logged.x();
    sample.y = logged.sample.logged.y();
    sample.covariance = {-1.0, 0.0, 0.0, 0.0};
    if (logged.sample.covariance) {
      for (int i = 0; i < 4; ++i) sample.covariance[i] = (*logged.sample.covariance)(i / 2, i % 2);
    }
    const ros::Time arrival = toRosTime(epoch, logged.arrival_s);
    stream.push_back({arrival, [&bag, &topics, &stats, sample, arrival] {
                        bag.write(topics.lens_shift_log, arrival, sample);
                        ++stats.lens_shift_log_messages;
                      }});
  }
  std::stable_sort(stream.begin(), stream.end(),
                   [](const Pending& a, const Pending& b) { return a.time < b.time; });
  std::size_t next = 0;

  sensor_msgs::CameraInfo info;
  info.header.frame_id = config.camera_frame_id;
  info.width = static_cast<uint32_t>(sensor.width_px);
  info.height = static_cast<uint32_t>(sensor.height_px);
  info.distortion_model = distortionModelName(camera.distortionModel());
  info.D = camera.coefficients();
  matrixToRowMajor(camera.K(), info.K.data());
  info.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) info.P[4 * r + c] = camera.K()(r, c);

  const int frames = simulator.frameCount();
  for (int k = 0; k < frames; ++k) {
    if (stop != nullptr && stop->load()) {
      stats.interrupted = true;
      break;
    }
    const ros::Time stamp = toRosTime(epoch, simulator.frameStamp(k));
    while (next < stream.size() && stream[next].time <= stamp) stream[next++].write();

    std_msgs::Header header;
    header.stamp = stamp;
    header.frame_id = config.camera_frame_id;
    const cv::Mat rgb = simulator.renderFrame(k);
    bag.write(topics.image, stamp, *cv_bridge::CvImage(header, sensor_msgs::image_encodings::RGB8, rgb).toImageMsg());
    info.header = header;
    bag.write(topics.camera_info, stamp, info);
    ++stats.frames;

    if (k >= 1) {
      const sim::FramePairTruth truth = simulator.pairTruth(k);
      FramePairTruth msg;
      msg.header = header;
      msg.previous_stamp = toRosTime(epoch, truth.stamp_a_s);
      msg.category = sim::toString(config.category);
      msg.ois_enabled = config.ois.enabled;
      msg.image_width = info.width;
      msg.image_height = info.height;
      msg.patch_count = static_cast<uint32_t>(truth.rotations_b_a.size());
      msg.readout_time = sensor.readout_time_s;
      msg.homographies_without_ois = flattenMatrices(truth.homographies_without_ois);
      msg.homographies_with_ois = flattenMatrices(truth.homographies_with_ois);
      msg.rotations = flattenMatrices(truth.rotations_b_a);
      msg.lens_shift_a = flattenPoints(truth.lens_shift_a_px);
      msg.lens_shift_b = flattenPoints(truth.lens_shift_b_px);
      msg.points_a = flattenPoints(truth.points_a_px);
      msg.points_b = flattenPoints(truth.points_b_px);
      bag.write(topics.frame_pair_truth, stamp, msg);
      ++stats.frame_pairs;
      stats.correspondences += static_cast<int>(truth.points_a_px.size());
    }
    if (progress) progress(k + 1, frames);
  }
  // The IMU runs past the last frame's rows; keep what belongs to the frames written.
  const ros::Time end = toRosTime(epoch, simulator.frameStamp(std::max(stats.frames - 1, 0)) +
                                             sensor.readout_time_s + 0.1);
  while (next < stream.size() && stream[next].time <= end) stream[next++].write();
  bag.close();
  return stats;
}

}  // namespace deep_ois
