// Issue 40 item 2: an applied calibration is not a time jump. Before GyroFlow.calibration_epoch, an
// applied decrease of the time offset moved the gyro flow's IMU times back by the change; the
// compensation took that for time going back, restarted its stabiliser model (warned "went back
// by") and dropped the online calibration's waiting pairs. Both live nodelets in one manager
// (live_calibration_change.test), fed in real time; the test applies offset changes of +10, -15,
// +1, -1, +15 and -10 ms through the gyro flow's online calibration input. After each change:
// - the gyro flows carry the new offset and a new calibration_epoch;
// - no restart is said, and every gyro flow gets its compensated flow;
// - the compensated homographies are exactly what the model, run without interruption on the gyro
//   stream the flows carry, answers at the new times (the output changes only by what the new
//   calibration changes);
// - /diagnostics counts every change as carried across, and no pair of the online calibration as
//   dropped.
#include <deep_ois/OnlineCalibration.h>
#include <diagnostic_msgs/DiagnosticArray.h>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "deep_ois/core/gyro/rolling_shutter_homographies.h"
#include "deep_ois/core/ois/stabiliser_compensator.h"
#include "deep_ois/core/ois/stabiliser_model_file.h"
#include "live_pipeline_rostest_helpers.h"

namespace deep_ois {
namespace {

using live_test::LivePipelineHarness;

LivePipelineHarness* harness = nullptr;

Eigen::Matrix3d rowMajor(const double* values) {
  Eigen::Matrix3d M;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) M(r, c) = values[3 * r + c];
  return M;
}

// Everything the test reads from the pipeline's outputs, by frame b's stamp.
class Recorder {
 public:
  Recorder() {
    ros::NodeHandle nh;
    gyro_sub_ = nh.subscribe<GyroFlow>(live_test::kGyroFlowTopic, 2000, [this](const GyroFlowConstPtr& m) {
      std::lock_guard<std::mutex> lock(mutex_);
      gyro_[m->header.stamp] = m;
    });
    compensated_sub_ =
        nh.subscribe<GyroFlow>(live_test::kCompensatedTopic, 2000, [this](const GyroFlowConstPtr& m) {
          std::lock_guard<std::mutex> lock(mutex_);
          compensated_[m->header.stamp] = m;
        });
    diagnostics_sub_ = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
        "/diagnostics", 100, [this](const diagnostic_msgs::DiagnosticArrayConstPtr& m) {
          std::lock_guard<std::mutex> lock(mutex_);
          for (const auto& status : m->status) {
            if (status.name.find("compensation") == std::string::npos) continue;
            for (const auto& kv : status.values) compensation_values_[kv.key] = kv.value;
          }
        });
    calibration_pub_ = nh.advertise<OnlineCalibration>("/test/online_calibration", 1, true);
  }

  // The gyro flow follows the test's calibration, and the test hears both flows from the first.
  bool connected() const {
    return calibration_pub_.getNumSubscribers() > 0 && gyro_sub_.getNumPublishers() > 0 &&
           compensated_sub_.getNumPublishers() > 0;
  }

  void apply(std::uint32_t version, double time_offset_s, double readout_time_s) {
    OnlineCalibration msg;
    msg.header.stamp = ros::Time::now();
    msg.state = OnlineCalibration::STATE_TRACKING;
    msg.version = version;
    msg.time_offset = time_offset_s;
    msg.readout_time = readout_time_s;
    msg.imu_to_camera_rotation = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    msg.estimate_imu_to_camera_rotation = msg.imu_to_camera_rotation;
    msg.mount_estimated = false;
    msg.confirmation = "applied by the test";
    calibration_pub_.publish(msg);
  }

  std::map<ros::Time, GyroFlowConstPtr> gyro() {
    std::lock_guard<std::mutex> lock(mutex_);
    return gyro_;
  }
  std::map<ros::Time, GyroFlowConstPtr> compensated() {
    std::lock_guard<std::mutex> lock(mutex_);
    return compensated_;
  }
  std::string compensationValue(const std::string& key) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto it = compensation_values_.find(key);
    return it == compensation_values_.end() ? std::string() : it->second;
  }

 private:
  ros::Subscriber gyro_sub_, compensated_sub_, diagnostics_sub_;
  ros::Publisher calibration_pub_;
  std::mutex mutex_;
  std::map<ros::Time, GyroFlowConstPtr> gyro_, compensated_;
  std::map<std::string, std::string> compensation_values_;
};

// The model run without interruption over the gyro stream of every gyro flow, in order, asked at
// each flow's own patch times: what the compensation publishes when nothing restarts it. Returns
// the largest difference of a compensated homography's entries (relative to the entry, at least
// 1) over the pairs both have, and how many it compared.
double largestDifferenceFromUninterrupted(const StabiliserModelFile& model,
                                          const std::map<ros::Time, GyroFlowConstPtr>& gyro,
                                          const std::map<ros::Time, GyroFlowConstPtr>& compensated,
                                          std::size_t* compared) {
  *compared = 0;
  double largest = 0.0;
  std::unique_ptr<StabiliserCompensator> reference;
  for (const auto& [stamp, flow] : gyro) {
    const Eigen::Matrix3d K = rowMajor(flow->K.data());
    if (!reference) reference = std::make_unique<StabiliserCompensator>(model.parameters, K);
    const double stamp_s = flow->header.stamp.toSec();
    std::vector<CameraRateSample> rates;
    for (std::size_t k = 0; k < flow->angular_velocity_times.size(); ++k) {
      rates.push_back({stamp_s + flow->angular_velocity_times[k],
                       Eigen::Vector3d(flow->angular_velocity[3 * k], flow->angular_velocity[3 * k + 1],
                                       flow->angular_velocity[3 * k + 2])});
    }
    reference->addRates(rates);
    const auto out = compensated.find(stamp);
    if (out == compensated.end()) continue;
    RollingShutterConfig rs;
    rs.patch_count = static_cast<int>(flow->patch_count);
    rs.readout_time_s = flow->readout_time;
    rs.time_offset_s = flow->time_offset;
    rs.patch_time = flow->patch_time_fraction > 0.25 ? PatchTimeReference::kPatchCentre : PatchTimeReference::kPatchStart;
    std::vector<double> times_a, times_b;
    std::vector<Eigen::Matrix3d> rotations;
    for (int i = 0; i < rs.patch_count; ++i) {
      times_a.push_back(patchImuTime(rs, flow->previous_stamp.toSec(), i));
      times_b.push_back(patchImuTime(rs, stamp_s, i));
      Eigen::Matrix3d R = K.inverse() * rowMajor(&flow->homographies[9 * static_cast<std::size_t>(i)]) * K;
      R /= std::cbrt(R.determinant());
      rotations.push_back(R);
    }
    const StabiliserCompensation expected = reference->compensate(rotations, times_a, times_b);
    if (!expected.ok) continue;  // the first pairs, before the reference's stream covers them
    ++*compared;
    for (int i = 0; i < rs.patch_count; ++i) {
      const Eigen::Matrix3d got = rowMajor(&out->second->homographies[9 * static_cast<std::size_t>(i)]);
      for (int e = 0; e < 9; ++e) {
        const double want = expected.homographies[static_cast<std::size_t>(i)](e / 3, e % 3);
        largest = std::max(largest, std::abs(got(e / 3, e % 3) - want) / std::max(1.0, std::abs(want)));
      }
    }
  }
  return largest;
}

TEST(LiveCalibrationChange, AnAppliedOffsetChangeIsCarriedAcrossNotTakenForATimeJump) {
  std::string model_path;
  ASSERT_TRUE(ros::NodeHandle("~").getParam("model", model_path));
  const StabiliserModelFile model = StabiliserModelFile::load(model_path);
  Recorder recorder;
  harness->publishTf();
  ASSERT_TRUE(harness->waitForPipeline());
  const ros::WallTime start = ros::WallTime::now();
  for (int k = 0; k < 200 && !recorder.connected(); ++k) ros::WallDuration(0.05).sleep();
  ASSERT_TRUE(recorder.connected()) << "the gyro flow does not follow /test/online_calibration, or the outputs "
                                       "did not connect";
  harness->stream(3.0);
  const GyroFlowConstPtr before = harness->lastGyroFlow();
  ASSERT_TRUE(before);
  const double readout_s = before->readout_time;
  const std::uint32_t first_epoch = before->calibration_epoch;
  // Offsets in ms after each change: +10, -15, +1, -1, +15, -10.
  const std::vector<double> offsets_ms = {10.0, -5.0, -4.0, -5.0, 10.0, 0.0};
  std::uint32_t version = 1;
  for (double offset_ms : offsets_ms) {
    recorder.apply(version++, 1e-3 * offset_ms, readout_s);
    harness->stream(1.5);
  }
  harness->stream(1.0);
  ros::WallDuration(0.5).sleep();  // the last outputs

  const std::map<ros::Time, GyroFlowConstPtr> gyro = recorder.gyro(), compensated = recorder.compensated();
  // Every offset was applied, each with a new epoch.
  std::vector<double> seen_offsets_ms;
  std::uint32_t last_epoch = first_epoch;
  std::size_t epochs = 0;
  for (const auto& [stamp, flow] : gyro) {
    if (flow->calibration_epoch != last_epoch) {
      ++epochs;
      last_epoch = flow->calibration_epoch;
      seen_offsets_ms.push_back(std::round(1e6 * flow->time_offset) / 1e3);
    }
  }
  EXPECT_EQ(epochs, offsets_ms.size());
  EXPECT_EQ(seen_offsets_ms, offsets_ms);

  // No restart: nothing said about time going back.
  EXPECT_TRUE(harness->warnings(start, {"compensation", "went back by"}).empty()) << harness->warningsText(start);
  // Every gyro flow after the first second got its compensated flow (the last half second may
  // still be on its way).
  const ros::Time first_counted = gyro.begin()->first + ros::Duration(1.0);
  const ros::Time last_counted = gyro.rbegin()->first - ros::Duration(0.5);
  std::size_t counted = 0, missing = 0;
  for (const auto& [stamp, flow] : gyro) {
    if (stamp < first_counted || stamp > last_counted) continue;
    ++counted;
    if (!compensated.count(stamp)) ++missing;
  }
  std::printf("[ measured ] %zu gyro flows over %zu calibration changes, %zu without a compensated flow\n", counted,
              epochs, missing);
  EXPECT_GE(counted, 250u);
  EXPECT_EQ(missing, 0u) << harness->warningsText(start);

  // The output is the uninterrupted model's at the new times.
  std::size_t compared = 0;
  const double largest = largestDifferenceFromUninterrupted(model, gyro, compensated, &compared);
  std::printf("[ measured ] %zu compensated flows against the uninterrupted model: largest relative difference %.3g\n",
              compared, largest);
  EXPECT_GE(compared, counted);
  EXPECT_LT(largest, 1e-9);

  // /diagnostics: every change carried across, no pair of the online calibration dropped.
  for (int k = 0; k < 40 && recorder.compensationValue("online calibration: counts").empty(); ++k)
    ros::WallDuration(0.1).sleep();
  EXPECT_EQ(recorder.compensationValue("stabiliser: calibration changes carried across"),
            std::to_string(offsets_ms.size()) + " (0 restarted: moved back beyond the model's history)");
  EXPECT_TRUE(recorder.compensationValue("stabiliser restarts after time went back").empty());
  const std::string counts = recorder.compensationValue("online calibration: counts");
  EXPECT_NE(counts.find(" 0 dropped"), std::string::npos) << counts;
  EXPECT_EQ(harness->nonFiniteOutputs(), 0u);
}

}  // namespace
}  // namespace deep_ois

int main(int argc, char** argv) {
  return deep_ois::live_test::runLivePipelineGtests(argc, argv, "test_live_calibration_change", deep_ois::harness);
}
