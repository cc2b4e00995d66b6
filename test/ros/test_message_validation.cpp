// gyroFlowProblem / compensationPairCheckProblem: every field of the messages the live nodelets
// read and publish (issue 31 item 11: a NaN homography passed through to compensated_flow).
#include <gtest/gtest.h>
#include <sensor_msgs/image_encodings.h>

#include <cstring>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "deep_ois/ros/messages/message_validation.h"

namespace deep_ois {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

GyroFlow validFlow() {
  GyroFlow m;
  m.header.stamp = ros::Time(100, 500);
  m.header.frame_id = "camera";
  m.previous_stamp = ros::Time(100, 0);
  m.image_width = 320;
  m.image_height = 240;
  m.patch_count = 2;
  for (int i = 0; i < 2; ++i) m.homographies.insert(m.homographies.end(), {1, 0, 0.5, 0, 1, -0.5, 0, 0, 1});
  m.K = {256, 0, 159.5, 0, 256, 119.5, 0, 0, 1};
  m.distortion_model = "plumb_bob";
  m.D = {0.01, -0.02, 0, 0, 0};
  m.readout_time = 0.02;
  m.time_offset = -0.001;
  m.patch_time_fraction = 0.5;
  m.imu_to_camera_rotation = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  m.angular_velocity_times = {-0.01, -0.005, 0.0};
  m.angular_velocity = {0.1, 0.2, 0.3, 0.1, 0.2, 0.3, 0.1, 0.2, 0.3};
  m.motion_model = GyroFlow::MOTION_GYRO;
  m.flow.encoding = sensor_msgs::image_encodings::TYPE_32FC2;
  m.flow.width = 4;
  m.flow.height = 3;
  m.flow.step = 4 * 8;
  m.flow.data.assign(m.flow.step * m.flow.height, 0);
  return m;
}

void setFlowValue(GyroFlow& m, std::size_t index, float value) {
  std::memcpy(&m.flow.data[4 * index], &value, sizeof value);
}

struct Broken {
  const char* what;
  std::function<void(GyroFlow&)> edit;
  const char* named;  // the field the problem must name
};

TEST(MessageValidation, AValidGyroFlowPasses) { EXPECT_EQ(gyroFlowProblem(validFlow()), ""); }

TEST(MessageValidation, EveryMalformedGyroFlowFieldIsNamed) {
  const std::vector<Broken> cases = {
      {"zero stamp", [](GyroFlow& m) { m.header.stamp = ros::Time(); m.previous_stamp = ros::Time(); }, "stamp"},
      {"previous after stamp", [](GyroFlow& m) { m.previous_stamp = m.header.stamp + ros::Duration(0.1); },
       "previous_stamp"},
      {"zero image size", [](GyroFlow& m) { m.image_width = 0; }, "image size"},
      {"zero patches", [](GyroFlow& m) { m.patch_count = 0; }, "patch_count"},
      {"patch count not the homographies'", [](GyroFlow& m) { m.patch_count = 3; }, "patch_count"},
      {"a homography value short", [](GyroFlow& m) { m.homographies.pop_back(); }, "patch_count"},
      {"NaN homography", [](GyroFlow& m) { m.homographies[4] = kNaN; }, "homographies[4]"},
      {"inf homography", [](GyroFlow& m) { m.homographies[11] = -kInf; }, "homographies[11]"},
      {"H[2][2] zero", [](GyroFlow& m) { m.homographies[17] = 0.0; }, "H[2][2]"},
      {"NaN K", [](GyroFlow& m) { m.K[2] = kNaN; }, "K[2]"},
      {"zero focal length", [](GyroFlow& m) { m.K[4] = 0.0; }, "focal"},
      {"NaN D", [](GyroFlow& m) { m.D[1] = kNaN; }, "D[1]"},
      {"NaN readout", [](GyroFlow& m) { m.readout_time = kNaN; }, "readout_time"},
      {"negative readout", [](GyroFlow& m) { m.readout_time = -0.01; }, "readout_time"},
      {"inf time offset", [](GyroFlow& m) { m.time_offset = kInf; }, "time_offset"},
      {"NaN patch time", [](GyroFlow& m) { m.patch_time_fraction = kNaN; }, "patch_time_fraction"},
      {"patch time beyond 1", [](GyroFlow& m) { m.patch_time_fraction = 1.5; }, "patch_time_fraction"},
      {"NaN rotation", [](GyroFlow& m) { m.imu_to_camera_rotation[8] = kNaN; }, "imu_to_camera_rotation[8]"},
      {"angular velocity short", [](GyroFlow& m) { m.angular_velocity.pop_back(); }, "angular_velocity"},
      {"NaN angular velocity time", [](GyroFlow& m) { m.angular_velocity_times[1] = kNaN; },
       "angular_velocity_times[1]"},
      {"times not increasing", [](GyroFlow& m) { m.angular_velocity_times[2] = -0.02; }, "angular_velocity_times[2]"},
      {"NaN angular velocity", [](GyroFlow& m) { m.angular_velocity[5] = kNaN; }, "angular_velocity[5]"},
      {"flow encoding", [](GyroFlow& m) { m.flow.encoding = "32FC1"; }, "flow encoding"},
      {"zero-size flow", [](GyroFlow& m) { m.flow.width = m.flow.height = 0; m.flow.data.clear(); }, "flow"},
      {"flow data short", [](GyroFlow& m) { m.flow.data.resize(10); }, "flow"},
      {"NaN flow", [](GyroFlow& m) { setFlowValue(m, 13, std::numeric_limits<float>::quiet_NaN()); }, "flow"},
      {"inf flow", [](GyroFlow& m) { setFlowValue(m, 0, std::numeric_limits<float>::infinity()); }, "flow"},
  };
  for (const Broken& c : cases) {
    GyroFlow m = validFlow();
    c.edit(m);
    const std::string problem = gyroFlowProblem(m);
    EXPECT_NE(problem, "") << c.what;
    EXPECT_NE(problem.find(c.named), std::string::npos) << c.what << ": " << problem;
  }
}

TEST(MessageValidation, FloatImagesAreCheckedAndIntegerOnesAreNot) {
  sensor_msgs::Image image;
  image.encoding = sensor_msgs::image_encodings::TYPE_32FC1;
  image.width = 2;
  image.height = 2;
  image.step = 12;  // padded rows: the padding is not read
  image.data.assign(24, 0);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(&image.data[8], &nan, 4);  // padding of row 0
  EXPECT_EQ(nonFiniteFloatImageProblem(image), "");
  std::memcpy(&image.data[16], &nan, 4);  // value 1 of row 1
  EXPECT_NE(nonFiniteFloatImageProblem(image).find("row 1"), std::string::npos);
  image.encoding = sensor_msgs::image_encodings::MONO8;
  EXPECT_EQ(nonFiniteFloatImageProblem(image), "");
}

CompensationPairCheck validCheck() {
  CompensationPairCheck m;
  m.header.stamp = ros::Time(100, 500);
  m.previous_stamp = ros::Time(100, 0);
  m.usable = true;
  m.tracks = 80;
  m.inliers = 70;
  m.model_residual = 0.4f;
  m.gyro_residual = 0.9f;
  m.confidence = 0.8f;
  return m;
}

TEST(MessageValidation, CompensationPairChecks) {
  EXPECT_EQ(compensationPairCheckProblem(validCheck()), "");
  // Not usable: NaN residuals are the message's "no verdict".
  CompensationPairCheck m = validCheck();
  m.usable = false;
  m.model_residual = m.gyro_residual = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(compensationPairCheckProblem(m), "");
  m.usable = true;
  EXPECT_NE(compensationPairCheckProblem(m).find("residuals"), std::string::npos);
  m = validCheck();
  m.confidence = std::numeric_limits<float>::quiet_NaN();
  EXPECT_NE(compensationPairCheckProblem(m).find("confidence"), std::string::npos);
  m = validCheck();
  m.inliers = 90;
  EXPECT_NE(compensationPairCheckProblem(m).find("inliers"), std::string::npos);
  m = validCheck();
  m.previous_stamp = m.header.stamp;
  EXPECT_NE(compensationPairCheckProblem(m).find("previous_stamp"), std::string::npos);
  // ~fusion's fields: a refined pair is valid; figures must be finite and >= 0, and a pair not
  // fused says nothing of a fusion.
  m = validCheck();
  m.fused = m.fusion_refined = true;
  m.fusion_mean_correction = 0.1f;
  m.fusion_max_correction = 0.3f;
  m.fusion_prior_sigma = 0.2f;
  m.fusion_reason = "refined on 120 tracks";
  EXPECT_EQ(compensationPairCheckProblem(m), "");
  m.fusion_max_correction = std::numeric_limits<float>::infinity();
  EXPECT_NE(compensationPairCheckProblem(m).find("fusion figure"), std::string::npos);
  m.fusion_max_correction = 0.3f;
  m.fused = false;
  EXPECT_NE(compensationPairCheckProblem(m).find("not fused"), std::string::npos);
}

}  // namespace
}  // namespace deep_ois
