// The calibration's ROS side: the YAML it writes is what the gyro flow nodelet's parameter loader
// reads; its static transform is the one the simulator writes to /tf_static; and the whole path
// (bag -> tracks -> estimate) on the committed sample bag and on an OIS recording made to the
// calibration protocol (rendered here by the simulator). No roscore needed.
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <tf2_msgs/TFMessage.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>

#include "deep_ois/core/calibration/rotation_alignment.h"
#include "deep_ois/ros/bag/calibration_bag_reader.h"
#include "deep_ois/core/calibration/calibration_yaml.h"
#include "deep_ois/core/calibration/lens_shift_log_calibration.h"
#include "deep_ois/ros/live/gyro_flow_parameters.h"
#include "deep_ois/ros/live/parameter_source.h"
#include "deep_ois/ros/bag/phone_recording_bag.h"
#include "deep_ois/tools/support/simulation_bag_writer.h"
#include "run_command.h"

namespace deep_ois {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

std::string sampleBag() { return std::string(DEEP_OIS_SOURCE_DIR) + "/bags/sample.bag"; }

CalibrationResult someResult() {
  CalibrationResult result;
  CameraImuCalibration& c = result.calibration;
  c.time_offset_s = -0.0371234567891;
  c.readout_time_s = 0.0187654321;
  c.gyro_bias_rad_s = Eigen::Vector3d(0.00312345, -0.0045678, 0.000987);
  c.imu_to_camera_rotation = expSO3(Eigen::Vector3d(0.02, -0.03, 0.05)) * signedAxisPermutations()[7];
  c.time_offset_sigma_s = 2e-5;
  result.pairs_used = 140;
  result.tracks_used = 50000;
  return result;
}

TEST(CalibrationYaml, RoundTripsThroughTheGyroFlowParameterLoader) {
  const CalibrationResult result = someResult();
  CalibrationProvenance provenance;
  provenance.source = "test.bag";
  provenance.imu_frame_id = "imu_link";
  provenance.camera_frame_id = "camera_optical_frame";
  const std::string path = ::testing::TempDir() + "/deep_ois_camera_imu.yaml";
  writeTextFile(path, calibrationYaml(result, provenance));

  const GyroFlowParameters p = loadGyroFlowParameters(YamlParameters(path));
  const CameraImuCalibration& c = result.calibration;
  EXPECT_NEAR(p.rolling_shutter.time_offset_s, c.time_offset_s, 1e-14);
  EXPECT_NEAR(p.rolling_shutter.readout_time_s, c.readout_time_s, 1e-14);
  EXPECT_FALSE(p.rotation_from_tf) << "the calibrated rotation must replace the tf lookup";
  EXPECT_TRUE(p.rolling_shutter.imu_to_camera_rotation.isApprox(c.imu_to_camera_rotation, 1e-13));
  EXPECT_TRUE(p.integration.gyro_bias_rad_s.isApprox(c.gyro_bias_rad_s, 1e-13));
  // Everything else keeps the loader's defaults: the file adds to config/gyro_flow.yaml.
  EXPECT_EQ(p.rolling_shutter.patch_count, 6);
  std::remove(path.c_str());
}

TEST(CalibrationYaml, StaticTransformIsTheOneTheSimulatorPublishes) {
  rosbag::Bag bag(sampleBag(), rosbag::bagmode::Read);
  const BagSequence sequence = readBagSequence(sampleBag());
  ASSERT_TRUE(sequence.imu_to_camera_rotation.has_value());
  bool found = false;
  for (const rosbag::MessageInstance& m : rosbag::View(bag, rosbag::TopicQuery("/tf_static"))) {
    const auto tf = m.instantiate<tf2_msgs::TFMessage>();
    ASSERT_TRUE(tf && !tf->transforms.empty());
    const auto& t = tf->transforms.front();
    const std::string command = staticTransformCommand(*sequence.imu_to_camera_rotation, t.header.frame_id,
                                                       t.child_frame_id);
    std::istringstream words(command);
    std::string rosrun, package, node;
    double x, y, z, qx, qy, qz, qw;
    std::string parent, child;
    words >> rosrun >> package >> node >> x >> y >> z >> qx >> qy >> qz >> qw >> parent >> child;
    EXPECT_EQ(parent, t.header.frame_id);
    EXPECT_EQ(child, t.child_frame_id);
    const Eigen::Quaterniond ours(qw, qx, qy, qz), theirs(t.transform.rotation.w, t.transform.rotation.x,
                                                         t.transform.rotation.y, t.transform.rotation.z);
    EXPECT_NEAR(std::abs(ours.dot(theirs)), 1.0, 1e-8) << command;
    found = true;
  }
  EXPECT_TRUE(found) << "the sample bag has no /tf_static";
}

TEST(CalibrationYaml, RefusedResultSaysSo) {
  CalibrationResult result = someResult();
  result.status = CalibrationStatus::kRefused;
  result.refusals = {"readout time: 1-sigma 3.000 ms exceeds 0.250 ms"};
  const std::string text = calibrationYaml(result, {});
  EXPECT_NE(text.find("# REFUSED (do not use): readout time"), std::string::npos) << text;
}

TEST(WriteTextFile, NamesAnUnwritablePath) {
  try {
    writeTextFile("/nonexistent_dir_deep_ois/x.yaml", "a: 1\n");
    FAIL() << "writing into a missing folder must fail";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent_dir_deep_ois/x.yaml"), std::string::npos);
  }
}

// The whole path on the committed sample bag (2 s, 256x192, OIS on: config/simulator/sample.yaml
// has time offset 0, readout 22 ms and the phone mount). Two seconds of an OIS camera are little
// signal, so the mount is held at the bag's tf as the README recommends for OIS cameras; the coarse
// stage must still find the mount on its own.
TEST(CalibrateBag, SampleBagGivesTheSimulatedTimingAndMount) {
  const CalibrationBag bag = readCalibrationBag(sampleBag(), CalibrationBagOptions());
  ASSERT_TRUE(bag.simulated_ois_enabled.has_value());
  EXPECT_TRUE(*bag.simulated_ois_enabled);
  ASSERT_TRUE(bag.tf_imu_to_camera_rotation.has_value());
  EXPECT_EQ(bag.data.pairs.size() + 1, bag.frames);
  CalibrationOptions options;
  options.lens_shift = LensShiftHandling::kPerFrameShift;
  const CalibrationResult free_mount = calibrateCameraImu(bag.data, options);
  EXPECT_EQ(free_mount.coarse_permutation_index, nearestSignedAxisPermutation(*bag.tf_imu_to_camera_rotation));
  options.estimate_rotation = false;
  options.imu_to_camera_rotation = *bag.tf_imu_to_camera_rotation;
  const CalibrationResult result = calibrateCameraImu(bag.data, options);
  const CameraImuCalibration& c = result.calibration;
  std::cout << "[ measured ] sample bag (mount held): offset " << c.time_offset_s * 1e3 << " ms (+- "
            << c.time_offset_sigma_s * 1e3 << "), readout " << c.readout_time_s * 1e3 << " ms (+- "
            << c.readout_time_sigma_s * 1e3 << "), " << result.pairs_used << " pairs, median residual "
            << result.median_residual_px << " px, " << bag.tracking_seconds << " s KLT, " << result.seconds
            << " s estimation" << (result.ok() ? "" : "; refused: " + result.reason()) << "\n";
  EXPECT_NEAR(c.time_offset_s, 0.0, 0.001);
  EXPECT_NEAR(c.readout_time_s, 0.022, 0.0015);
}

// An OIS camera recorded the way README "Calibration" asks (config/simulator/calibration.yaml: 10 s
// of deliberate turns about all three axes, the scene 4 m away or more), rendered, tracked and
// calibrated with every quantity free: the target of 0.5 ms / 0.5 ms / 0.5 degree holds through the
// lens, and the estimate is accepted. The same tracks with the lens ignored miss the target, so the
// lens model is what this measures. The truth is one the benchmark could have drawn.
TEST(CalibrateBag, OisCameraRecordedToTheProtocolIsWithinTarget) {
  sim::SimulatorConfig config =
      sim::loadSimulatorConfig(std::string(DEEP_OIS_SOURCE_DIR) + "/config/simulator/calibration.yaml");
  ASSERT_TRUE(config.ois.enabled);
  config.imu.time_offset_s = 0.0312;
  config.sensor.readout_time_s = 0.0147;
  config.imu.imu_to_camera_rotation =
      expSO3(Eigen::Vector3d(1.0, -2.0, 1.5).normalized() * 3.0 * kDeg) * signedAxisPermutations()[17];
  config.imu.gyro_initial_bias_vector_rad_s = Eigen::Vector3d(0.006, -0.004, 0.008);
  const std::string path = ::testing::TempDir() + "/deep_ois_calibration_protocol_ois.bag";
  {
    const sim::Simulator simulator(config, 505, 10.0);
    writeSimulationBag(simulator, path, rosbag::compression::LZ4, SimulationBagTopics{}, nullptr);
  }
  const CalibrationBag bag = readCalibrationBag(path, CalibrationBagOptions());
  std::remove(path.c_str());
  ASSERT_TRUE(bag.simulated_ois_enabled.value_or(false));

  // Errors of an estimate against the simulated truth: ms, ms, degrees.
  auto errorsOf = [&config](const CameraImuCalibration& c) {
    return Eigen::Vector3d((c.time_offset_s - config.imu.time_offset_s) * 1e3,
                           (c.readout_time_s - config.sensor.readout_time_s) * 1e3,
                           rotationAngleBetween(c.imu_to_camera_rotation, config.imu.imu_to_camera_rotation) / kDeg);
  };
  CalibrationOptions options;
  options.lens_shift = LensShiftHandling::kPerFrameShift;
  const CalibrationResult result = calibrateCameraImu(bag.data, options);
  const CameraImuCalibration& c = result.calibration;
  const Eigen::Vector3d error = errorsOf(c);
  std::cout << "[ measured ] OIS, calibration protocol (10 s, 360x270): offset error " << error(0) << " ms (+- "
            << c.time_offset_sigma_s * 1e3 << "), readout error " << error(1) << " ms (+- "
            << c.readout_time_sigma_s * 1e3 << "), rotation error " << error(2) << " deg (+- "
            << c.rotation_sigma_rad.maxCoeff() / kDeg << " max axis), " << result.pairs_used << " pairs, "
            << result.tracks_used << " tracks, " << bag.tracking_seconds << " s KLT, " << result.seconds
            << " s estimation" << (result.ok() ? "" : "; refused: " + result.reason()) << "\n";
  EXPECT_TRUE(result.ok()) << result.reason();
  EXPECT_EQ(result.coarse_permutation_index, 17);
  EXPECT_LT(std::abs(error(0)), 0.5);
  EXPECT_LT(std::abs(error(1)), 0.5);
  EXPECT_LT(error(2), 0.5);

  CalibrationOptions fixed_lens;
  fixed_lens.max_iterations = 15;  // it only has to show how far off it is
  const Eigen::Vector3d ignored = errorsOf(calibrateCameraImu(bag.data, fixed_lens).calibration);
  std::cout << "[ measured ] same tracks, lens ignored: offset error " << ignored(0) << " ms, readout error "
            << ignored(1) << " ms, rotation error " << ignored(2) << " deg\n";
  // Outside the target (here the readout, by 0.83 ms; over the benchmark's 24 protocol OIS bags the
  // fixed-lens estimate misses it on 20, with readout errors up to 2.9 ms).
  EXPECT_GT(ignored.cwiseAbs().maxCoeff(), 0.5);
}

// A hand-held OIS recording whose camera logs its lens in its own convention (a scale, the axes
// swapped, one sign flipped, its clock 7 ms behind): calibrate's lens-shift step recovers the
// offset within 0.5 ms, the scale within 2 % and the swap and signs exactly, from the images and
// the gyro (the camera-IMU calibration held at the simulated truth).
TEST(CalibrateBag, LensShiftLogConventionRecoveredFromTheImages) {
  sim::SimulatorConfig config =
      sim::loadSimulatorConfig(std::string(DEEP_OIS_SOURCE_DIR) + "/config/simulator/RE.yaml");
  ASSERT_TRUE(config.ois.enabled && config.lens_log.enabled);
  config.imu.time_offset_s = 0.004;
  config.sensor.readout_time_s = 0.018;
  LensShiftLogConvention& truth = config.lens_log.convention;
  truth.scale = 1.25;
  truth.swap_xy = true;
  truth.sign_x = 1.0;
  truth.sign_y = -1.0;
  truth.time_offset_s = -0.007;
  const std::string path = ::testing::TempDir() + "/deep_ois_lens_log_convention.bag";
  {
    const sim::Simulator simulator(config, 2024, 3.0);
    writeSimulationBag(simulator, path, rosbag::compression::LZ4, SimulationBagTopics{}, nullptr);
  }
  const CalibrationBag bag = readCalibrationBag(path, CalibrationBagOptions());
  std::remove(path.c_str());
  ASSERT_FALSE(bag.lens_shift_log.empty());

  CameraImuCalibration known;
  known.time_offset_s = config.imu.time_offset_s;
  known.readout_time_s = config.sensor.readout_time_s;
  known.imu_to_camera_rotation = config.imu.imu_to_camera_rotation;
  const LensShiftLogCalibration lens = calibrateLensShiftLog(bag.data, known, bag.lens_shift_log);
  const LensShiftLogConvention& c = lens.convention;
  std::cout << "[ measured ] lens-shift log convention: offset " << c.time_offset_s * 1e3 << " ms (truth "
            << truth.time_offset_s * 1e3 << "), scale " << c.scale << " (truth " << truth.scale << "), swap "
            << c.swap_xy << ", signs " << c.sign_x << " " << c.sign_y << "; " << lens.observations
            << " observations, residual " << lens.residual_rms_px << " px, signal " << lens.lens_motion_rms_px
            << " px" << (lens.ok ? "" : "; refused: " + lens.problem) << "\n";
  ASSERT_TRUE(lens.ok) << lens.problem;
  EXPECT_LT(std::abs(c.time_offset_s - truth.time_offset_s), 0.0005);
  EXPECT_LT(std::abs(c.scale / truth.scale - 1.0), 0.02);
  EXPECT_EQ(c.swap_xy, truth.swap_xy);
  EXPECT_EQ(c.sign_x, truth.sign_x);
  EXPECT_EQ(c.sign_y, truth.sign_y);

  // Without a log there is nothing to fit: refused with a reason, not a made-up convention.
  const LensShiftLogCalibration none = calibrateLensShiftLog(bag.data, known, {});
  EXPECT_FALSE(none.ok);
  EXPECT_NE(none.problem.find("no lens-shift log"), std::string::npos);
}

}  // namespace
}  // namespace deep_ois

namespace deep_ois {
namespace {

// Issue 23 #9: a refused calibrate prints the refusal and the figures that led to it, and no
// estimate (it printed "time offset -14.547 ms +- 0.000 ms" and "0 tracks" from a refinement that
// never ran). A still camera: 40 identical textured frames and a gyro that reads only noise.
TEST(CalibrateTool, RefusalPrintsTheReasonAndItsFiguresOnly) {
  const std::string dir = ::testing::TempDir() + "/calibrate_refusal";
  std::filesystem::create_directories(dir);
  const std::string bag_path = dir + "/still.bag";
  RecordingContent content;
  content.gyro_source = "gyro";
  for (int k = 0; k < 400; ++k) {
    ImuSample sample;
    sample.stamp_s = 100.0 + 0.005 * k;
    sample.angular_velocity_rad_s = Eigen::Vector3d(1e-4 * std::sin(k), 1e-4 * std::cos(k), 0.0);
    content.gyro.push_back(sample);
  }
  content.frames_source = "frames";
  for (int f = 0; f < 40; ++f) content.frames.push_back({f, 100.2 + f / 30.0, "frame " + std::to_string(f)});
  cv::Mat texture(240, 320, CV_8UC1);
  cv::randu(texture, 0, 255);
  cv::GaussianBlur(texture, texture, cv::Size(0, 0), 2.0);
  content.read_image = [texture](std::size_t) { return texture.clone(); };
  content.camera_info = makePinholeCameraInfo(320, 240, 300, 300, 159.5, 119.5);
  PhoneRecordingBagOptions options;
  options.imu_to_camera_rotation = Eigen::Matrix3d::Identity();
  writeRecordingBag(std::move(content), bag_path, options);

  std::string output;
  EXPECT_EQ(test::runCommand(std::string(DEEP_OIS_CALIBRATE_EXE) + " --quiet --bag " + bag_path + " --out " + dir +
                                 "/cal.yaml 2>&1",
                             output),
            1)
      << output;
  EXPECT_NE(output.find("calibrate: refused, " + dir + "/cal.yaml not written"), std::string::npos) << output;
  EXPECT_NE(output.find("the camera hardly rotates"), std::string::npos) << output;
  EXPECT_NE(output.find("figures: " + bag_path + ": 40 frames"), std::string::npos) << output;
  EXPECT_NE(output.find("gyro RMS about its principal axes"), std::string::npos) << output;
  // No estimate, no placeholder.
  for (const char* placeholder : {"time offset ", "readout time ", "R_cam_imu", "+- 0.000", " 0 tracks", "refined in"})
    EXPECT_EQ(output.find(placeholder), std::string::npos) << "'" << placeholder << "' in:\n" << output;
  EXPECT_FALSE(std::filesystem::exists(dir + "/cal.yaml"));
}

}  // namespace
}  // namespace deep_ois
