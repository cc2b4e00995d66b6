// Writes a simulated sequence into a rosbag with the topics a real robot records plus the
// simulator's ground truth.
#pragma once

#include <rosbag/bag.h>

#include <atomic>
#include <functional>
#include <string>

#include "deep_ois/core/sim/simulator.h"

namespace deep_ois {

struct SimulationBagTopics {
  std::string image = "/camera/image_raw";           // sensor_msgs/Image, rgb8
  std::string camera_info = "/camera/camera_info";   // sensor_msgs/CameraInfo, plumb_bob
  std::string imu = "/imu/data";                     // sensor_msgs/Imu, IMU frame, IMU clock
  std::string tf_static = "/tf_static";              // IMU -> camera optical frame, latched
  std::string frame_pair_truth = "/ground_truth/frame_pair";  // deep_ois/FramePairTruth
  std::string lens_shift = "/ground_truth/lens_shift";        // deep_ois/LensShift
  // The camera's own lens log (deep_ois/LensShiftSample), recorded at its arrival time.
  std::string lens_shift_log = "/camera/lens_shift";
};

struct SimulationBagStats {
  int frames = 0;
  int frame_pairs = 0;
  int imu_messages = 0;
  int lens_shift_messages = 0;
  int lens_shift_log_messages = 0;
  int correspondences = 0;
  bool interrupted = false;  // stopped early by `stop`; the bag holds every frame written so far
};

// Renders every frame of `simulator` and writes the bag at `path` (messages in time order, bag
// time = header stamp, camera stamps on the camera clock from config.start_epoch_s, IMU stamps on
// the IMU clock). `progress(frames_done, frames_total)` is called after each frame. When `stop`
// becomes true the bag is closed after the current frame. Throws rosbag::BagException when the
// file cannot be written.
SimulationBagStats writeSimulationBag(const sim::Simulator& simulator, const std::string& path,
                                      rosbag::compression::CompressionType compression,
                                      const SimulationBagTopics& topics,
                                      const std::function<void(int, int)>& progress,
                                      const std::atomic<bool>* stop = nullptr);

}  // namespace deep_ois
