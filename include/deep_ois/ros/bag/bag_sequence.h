// Reads the non-image content of a recording (IMU stream, frame stamps, camera_info, static tf,
// simulator ground truth) from a rosbag, for offline tools and tests that run the same core code
// as the nodelets.
#pragma once

#include <deep_ois/FramePairTruth.h>
#include <ros/time.h>

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "deep_ois/core/camera/camera_model.h"
#include "deep_ois/core/gyro/imu_sample_buffer.h"
#include "deep_ois/core/ois/lens_shift_log.h"
#include "deep_ois/ros/bag/bag_frame_reader.h"

namespace deep_ois {

struct BagSequenceTopics {
  std::string image = "/camera/image_raw";
  std::string camera_info = "/camera/camera_info";
  std::string imu = "/imu/data";
  std::string frame_pair_truth = "/ground_truth/frame_pair";
  std::string lens_shift_log = "/camera/lens_shift";  // the camera's own lens log, if it has one
};

// What readBagSequence does when a message cannot be read part-way through an indexed bag (a
// corrupt chunk: the bag opens, a chunk in the middle does not decompress).
enum class BagReadFailure {
  kThrow,       // throw: scores must not silently come from part of a recording
  kKeepPrefix,  // keep everything read before the failure and say why in read_error
};

struct BagSequence {
  std::string path;
  ros::Time time_base;  // imu samples' stamps are seconds since this
  std::vector<ImuSample> imu_samples;
  std::string imu_frame_id;
  std::vector<ros::Time> frame_stamps;  // stamps of the camera_info messages, in bag order
  std::string camera_frame_id;
  std::optional<CameraModel> camera;   // from the first camera_info
  std::string distortion_model;
  // R_cam_imu from /tf_static (lookup camera frame <- IMU frame); empty when the bag has no such
  // transform.
  std::optional<Eigen::Matrix3d> imu_to_camera_rotation;
  // Why imu_to_camera_rotation is empty, naming the cause: no IMU message on the topic (then
  // there is no IMU frame to look up; the sentence lists the bag's sensor_msgs/Imu topics), a
  // camera_info without frame_id, or no transform between the two frames. Empty when found.
  std::string imu_to_camera_problem;
  // Empty when imu_samples is not; otherwise "no IMU messages on <topic> ...", as above.
  std::string imu_problem;
  std::vector<FramePairTruth> truths;  // empty for a real recording
  // The camera's lens-shift log (deep_ois/LensShiftSample) in bag order, stamps in seconds since
  // time_base on the log's clock, values as logged; empty when the bag has none.
  std::vector<LensShiftLogSample> lens_shift_log;
  // kKeepPrefix only: empty when the whole bag was read; otherwise a sentence naming the bag,
  // where reading stopped and why. The fields above then hold the messages before that point.
  std::string read_error;

  double secondsSinceBase(const ros::Time& stamp) const { return (stamp - time_base).toSec(); }
  // A buffer holding every IMU sample (duration-bounded buffers would drop the early ones).
  ImuSampleBuffer imuBuffer() const;
};

// Throws std::runtime_error naming the file and the problem (unreadable bag, no camera_info, a
// camera_info that is not usable, IMU samples rejected by the buffer's rules, and with kThrow a
// message that cannot be read).
//
// When `frames` is not null, the images on topics.image are decoded into it (bag order) in the same
// pass: images and IMU share the bag's compressed chunks, so reading both at once decompresses each
// chunk once instead of twice (an image that cannot be decoded is then an error naming the bag).
BagSequence readBagSequence(const std::string& path, const BagSequenceTopics& topics = {},
                            BagReadFailure on_failure = BagReadFailure::kThrow,
                            std::vector<BagFrame>* frames = nullptr);

}  // namespace deep_ois
