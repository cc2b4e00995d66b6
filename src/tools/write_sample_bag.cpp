// Writes a short rosbag of a synthetic hand-held rotating camera (rolling-shutter RGB frames,
// camera_info, gyroscope, static IMU -> camera transform), so the gyro flow nodelet can be run
// and tested with nothing but this package. The simulation itself lives in the core
// (SyntheticRotationSequence); this file only parses arguments and writes messages.
#include <ros/time.h>
#include <rosbag/bag.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <tf2_msgs/TFMessage.h>

#include <Eigen/Geometry>
#include <boost/make_shared.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>

#include "deep_ois/core/synthetic_rotation_sequence.h"

namespace deep_ois {
namespace {

constexpr const char* kImageTopic = "/camera/image_raw";
constexpr const char* kCameraInfoTopic = "/camera/camera_info";
constexpr const char* kImuTopic = "/imu/data";
constexpr const char* kTfStaticTopic = "/tf_static";
constexpr const char* kCameraFrame = "camera_optical_frame";
constexpr const char* kImuFrame = "imu_link";
// Stamps start at a realistic epoch (2023-11-14) rather than 0, as a real recording would.
constexpr std::uint32_t kEpochSeconds = 1700000000u;
// A phone-grade gyroscope: ~0.007 deg/s/sqrt(Hz) over a 200 Hz bandwidth is ~0.002 rad/s per
// sample. The bag carries this noise by default so that its covariance is the truth.
constexpr double kDefaultGyroNoiseRadS = 0.002;
constexpr double kAccelerometerStdMS2 = 0.03;  // nominal, reported in the covariance only
constexpr double kGravityMS2 = 9.80665;

const char* kUsage =
    "usage: write_sample_bag --out FILE.bag [--seed N] [--duration S] [--width W --height H]\n"
    "                        [--readout S] [--imu-rate HZ] [--gyro-noise RAD_S] [--save-frame "
    "FILE.png]\n"
    "  --out         bag to write (overwritten)\n"
    "  --seed        motion and scene seed, default 1\n"
    "  --duration    seconds of video at 30 fps, default 3\n"
    "  --width/--height  image size in pixels, default 360x270 (70 deg horizontal field of view)\n"
    "  --readout     rolling-shutter readout time in seconds, default 0.022 (0 = global shutter)\n"
    "  --imu-rate    gyroscope rate in Hz, default 400\n"
    "  --gyro-noise  white gyro noise per sample and axis in rad/s, default 0.002 (0 = exact)\n"
    "  --save-frame  also save frame 0 as an image file (for a quick look)\n";

struct Options {
  std::string out_path;
  std::string frame_path;
  SyntheticSequenceConfig sequence;
};

// Thrown for a command-line mistake; the message names the flag.
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

double parseNumber(const std::string& flag, const std::string& text) {
  std::size_t used = 0;
  double value = 0.0;
  try {
    value = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size() || !std::isfinite(value)) {
    throw UsageError(flag + " needs a number, got '" + text + "'");
  }
  return value;
}

int parseInteger(const std::string& flag, const std::string& text, long min_value, long max_value) {
  const double value = parseNumber(flag, text);
  if (value != std::floor(value) || value < min_value || value > max_value) {
    throw UsageError(flag + " needs an integer in [" + std::to_string(min_value) + ", " +
                     std::to_string(max_value) + "], got '" + text + "'");
  }
  return static_cast<int>(value);
}

Options parseArguments(int argc, char** argv) {
  Options options;
  SyntheticSequenceConfig& c = options.sequence;
  c.gyro_noise_std_rad_s = kDefaultGyroNoiseRadS;
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (flag == "-h" || flag == "--help") {
      std::cout << kUsage;
      std::exit(0);
    }
    if (flag.rfind("--", 0) != 0) throw UsageError("unexpected argument '" + flag + "'");
    if (i + 1 >= argc) throw UsageError(flag + " needs a value");
    const std::string value = argv[++i];
    if (flag == "--out") {
      options.out_path = value;
    } else if (flag == "--save-frame") {
      options.frame_path = value;
    } else if (flag == "--seed") {
      c.seed = static_cast<std::uint32_t>(parseInteger(flag, value, 0, 2147483647L));
    } else if (flag == "--duration") {
      c.duration_s = parseNumber(flag, value);
      if (c.duration_s * c.frame_rate_hz < 2.0 || c.duration_s > 600.0) {
        throw UsageError("--duration must be between 2 frames (0.067 s) and 600 s, got " + value);
      }
    } else if (flag == "--width") {
      c.width_px = parseInteger(flag, value, 16, 8192);
    } else if (flag == "--height") {
      c.height_px = parseInteger(flag, value, 16, 8192);
    } else if (flag == "--readout") {
      c.readout_time_s = parseNumber(flag, value);
      if (c.readout_time_s < 0.0 || c.readout_time_s >= 1.0 / c.frame_rate_hz) {
        throw UsageError("--readout must be in [0, 0.0333) s (shorter than a frame), got " + value);
      }
    } else if (flag == "--imu-rate") {
      c.imu_rate_hz = parseNumber(flag, value);
      if (c.imu_rate_hz < 50.0 || c.imu_rate_hz > c.integration_rate_hz) {
        throw UsageError("--imu-rate must be in [50, 4000] Hz, got " + value);
      }
    } else if (flag == "--gyro-noise") {
      c.gyro_noise_std_rad_s = parseNumber(flag, value);
      if (c.gyro_noise_std_rad_s < 0.0) throw UsageError("--gyro-noise must be >= 0, got " + value);
    } else {
      throw UsageError("unknown flag '" + flag + "'");
    }
  }
  if (options.out_path.empty()) throw UsageError("--out is required");
  const std::string problem = c.validate();
  if (!problem.empty()) throw UsageError(problem);
  return options;
}

ros::Time stampAt(double sequence_time_s) {
  return ros::Time(kEpochSeconds, 0) + ros::Duration(sequence_time_s);
}

geometry_msgs::Quaternion toMsg(const Eigen::Matrix3d& rotation) {
  const Eigen::Quaterniond q(rotation);
  geometry_msgs::Quaternion msg;
  msg.x = q.x();
  msg.y = q.y();
  msg.z = q.z();
  msg.w = q.w();
  return msg;
}

sensor_msgs::CameraInfo cameraInfo(const CameraModel& camera) {
  sensor_msgs::CameraInfo info;
  info.header.frame_id = kCameraFrame;
  info.width = camera.width();
  info.height = camera.height();
  info.distortion_model = "plumb_bob";
  info.D.assign(5, 0.0);
  for (int k = 0; k < 5; ++k) info.D[k] = camera.distortion()[k];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      info.K[3 * r + c] = camera.K()(r, c);
      info.R[3 * r + c] = r == c ? 1.0 : 0.0;
      info.P[4 * r + c] = camera.K()(r, c);
    }
  }
  return info;
}

// The camera's pose in the IMU frame (parent imu_link, child camera_optical_frame), so that
// lookupTransform(target = camera_optical_frame, source = imu_link) yields R_cam_imu.
tf2_msgs::TFMessage imuToCameraTransform(const Eigen::Matrix3d& R_cam_imu, const ros::Time& stamp) {
  geometry_msgs::TransformStamped transform;
  transform.header.stamp = stamp;
  transform.header.frame_id = kImuFrame;
  transform.child_frame_id = kCameraFrame;
  transform.transform.rotation = toMsg(R_cam_imu.transpose());
  tf2_msgs::TFMessage message;
  message.transforms.push_back(transform);
  return message;
}

// A connection header like a latched publisher's, so that `rosbag play` republishes it latched.
boost::shared_ptr<ros::M_string> latchedConnectionHeader(const std::string& topic) {
  auto header = boost::make_shared<ros::M_string>();
  (*header)["topic"] = topic;
  (*header)["type"] = ros::message_traits::datatype<tf2_msgs::TFMessage>();
  (*header)["md5sum"] = ros::message_traits::md5sum<tf2_msgs::TFMessage>();
  (*header)["message_definition"] = ros::message_traits::definition<tf2_msgs::TFMessage>();
  (*header)["callerid"] = "/write_sample_bag";
  (*header)["latching"] = "1";
  return header;
}

int run(const Options& options) {
  const auto start = std::chrono::steady_clock::now();
  const SyntheticRotationSequence sequence(options.sequence);
  const SyntheticSequenceConfig& config = sequence.config();
  const std::vector<ImuSample>& imu = sequence.imuSamples();

  rosbag::Bag bag;
  bag.open(options.out_path, rosbag::bagmode::Write);
  // BZ2: the frames are most of the bag and compress ~5x; LZ4 only manages ~1.5x.
  bag.setCompression(rosbag::compression::BZ2);

  const ros::Time first_stamp = stampAt(imu.front().stamp_s);
  bag.write(kTfStaticTopic, first_stamp,
            imuToCameraTransform(config.imu_to_camera_rotation, first_stamp),
            latchedConnectionHeader(kTfStaticTopic));

  sensor_msgs::Imu imu_msg;
  imu_msg.header.frame_id = kImuFrame;
  imu_msg.orientation.w = 1.0;
  imu_msg.orientation_covariance[0] = -1.0;  // no orientation estimate
  const double gyro_std =
      config.gyro_noise_std_rad_s > 0.0 ? config.gyro_noise_std_rad_s : kDefaultGyroNoiseRadS;
  for (int k = 0; k < 3; ++k) {
    imu_msg.angular_velocity_covariance[4 * k] = gyro_std * gyro_std;
    imu_msg.linear_acceleration_covariance[4 * k] = kAccelerometerStdMS2 * kAccelerometerStdMS2;
  }
  const sensor_msgs::CameraInfo info_template = cameraInfo(sequence.camera());

  // Messages in time order: every IMU sample stamped up to a frame goes before that frame.
  std::size_t next_imu = 0;
  std::uint32_t imu_seq = 0;
  auto writeImuUntil = [&](double sequence_time_s) {
    for (; next_imu < imu.size() && imu[next_imu].stamp_s <= sequence_time_s; ++next_imu) {
      const ImuSample& sample = imu[next_imu];
      imu_msg.header.seq = imu_seq++;
      imu_msg.header.stamp = stampAt(sample.stamp_s);
      imu_msg.angular_velocity.x = sample.angular_velocity_rad_s.x();
      imu_msg.angular_velocity.y = sample.angular_velocity_rad_s.y();
      imu_msg.angular_velocity.z = sample.angular_velocity_rad_s.z();
      // Pure rotation about the camera centre: the accelerometer feels only gravity (world z up).
      const Eigen::Matrix3d R_world_imu =
          sequence.orientation(sample.stamp_s - config.time_offset_s) *
          config.imu_to_camera_rotation;
      const Eigen::Vector3d specific_force =
          R_world_imu.transpose() * Eigen::Vector3d(0.0, 0.0, kGravityMS2);
      imu_msg.linear_acceleration.x = specific_force.x();
      imu_msg.linear_acceleration.y = specific_force.y();
      imu_msg.linear_acceleration.z = specific_force.z();
      bag.write(kImuTopic, imu_msg.header.stamp, imu_msg);
    }
  };

  cv::Mat rgb;
  for (int frame = 0; frame < sequence.frameCount(); ++frame) {
    const double stamp_s = sequence.frameStamp(frame);
    // IMU clock = camera clock + offset: compare both on the IMU clock.
    writeImuUntil(stamp_s + config.time_offset_s);
    sequence.renderFrame(frame, rgb);
    if (frame == 0 && !options.frame_path.empty()) {
      cv::Mat bgr;
      cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
      if (!cv::imwrite(options.frame_path, bgr)) {
        std::cerr << "write_sample_bag: could not save frame to " << options.frame_path << "\n";
      }
    }
    auto image = boost::make_shared<sensor_msgs::Image>();
    image->header.seq = frame;
    image->header.stamp = stampAt(stamp_s);
    image->header.frame_id = kCameraFrame;
    image->height = rgb.rows;
    image->width = rgb.cols;
    image->encoding = "rgb8";
    image->is_bigendian = 0;
    image->step = static_cast<std::uint32_t>(rgb.cols * 3);
    image->data.assign(rgb.data, rgb.data + rgb.total() * rgb.elemSize());
    sensor_msgs::CameraInfo info = info_template;
    info.header = image->header;
    bag.write(kImageTopic, image->header.stamp, image);
    bag.write(kCameraInfoTopic, info.header.stamp, info);
  }
  writeImuUntil(imu.back().stamp_s);
  bag.close();

  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::ifstream written(options.out_path, std::ios::binary | std::ios::ate);
  const double megabytes = static_cast<double>(written.tellg()) / 1e6;
  std::printf(
      "write_sample_bag: %s: %d frames %dx%d rgb8 at %.0f fps (readout %.1f ms), %zu IMU samples "
      "at %.0f Hz, %.2f s of video (IMU %.2f s), seed %u, %.2f MB, written in %.1f s\n",
      options.out_path.c_str(), sequence.frameCount(), config.width_px, config.height_px,
      config.frame_rate_hz, config.readout_time_s * 1e3, imu.size(), config.imu_rate_hz,
      sequence.frameCount() / config.frame_rate_hz, imu.back().stamp_s - imu.front().stamp_s,
      config.seed, megabytes, seconds);
  return 0;
}

}  // namespace
}  // namespace deep_ois

int main(int argc, char** argv) {
  deep_ois::Options options;
  try {
    options = deep_ois::parseArguments(argc, argv);
  } catch (const deep_ois::UsageError& error) {
    std::cerr << "write_sample_bag: " << error.what() << "\n" << deep_ois::kUsage;
    return 2;
  }
  try {
    return deep_ois::run(options);
  } catch (const std::exception& error) {
    std::cerr << "write_sample_bag: " << error.what() << "\n";
    return 1;
  }
}
