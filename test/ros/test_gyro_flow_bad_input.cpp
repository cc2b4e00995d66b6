// rostest of the deep_ois/gyro_flow nodelet on a stream with bad input, one kind per phase and good
// frames in between: (a) NaN/inf angular rates, (b) reversed and duplicate IMU stamps, (c) an IMU
// gap, (d) unusable images, (e) a degenerate camera_info, (f) duplicate and out-of-order camera
// stamps, (g) IMU messages in a frame that tf does not know, (h) the whole stream jumping back
// 10 s as when a bag loops.
//
// The test states, for every frame pair, whether the nodelet must publish it, must not, or may do
// either, from a model of the input contract written here (not from the wrapper's code):
//  - frames with an unusable image or camera_info, and frames not newer than the latest frame,
//    are ignored; the next usable frame pairs with the latest usable one;
//  - IMU messages with a non-finite rate, a stamp not newer than the newest one, or a frame
//    without a transform to the camera are unusable; a pair is computable when the usable samples
//    around its IMU interval are nowhere further apart than ~max_imu_gap;
//  - a stamp far older than the newest one (a bag loop) starts the pairing afresh.
// Every published GyroFlow must match the analytic motion, and each frame is published once.
#include <algorithm>
#include <iostream>
#include <map>
#include <sstream>

#include "gyro_flow_rostest_helpers.h"

namespace deep_ois {
namespace {

using namespace rostest_helpers;

constexpr double kImuLeadS = 0.05;        // IMU messages go out this much (stamp time) before frames
constexpr double kPlaybackSpeed = 2.0;    // faster than real time, in stamp order
constexpr double kLoopJumpS = 10.0;       // (h): stamps jump back by this much
constexpr double kLoopPauseKeyS = 1.5;    // stream time between the loop's two segments
constexpr double kDeliveryJitterS = 0.15;  // stream time a frame may arrive after its IMU
constexpr int kSegment1Frames = 130;
constexpr int kSegment2Frames = 20;
constexpr char kUntrackedImuFrame[] = "imu_link_untracked";  // (g): no transform in tf

enum class Expect { kPublish, kSilent, kEither };

const char* toString(Expect expect) {
  switch (expect) {
    case Expect::kPublish: return "must publish";
    case Expect::kSilent: return "must not publish";
    case Expect::kEither: return "may publish";
  }
  return "?";
}

// One planned IMU message.
struct ImuPlan {
  ros::Time stamp;
  double key_s = 0.0;
  std::string frame_id = kImuFrame;
  Eigen::Vector3d rate_rad_s = Eigen::Vector3d::Zero();  // in frame_id
  bool usable = true;     // per the input contract above
  bool untracked = false;  // (g)
};

// One planned camera frame (image + camera_info).
struct FramePlan {
  ros::Time stamp;
  double key_s = 0.0;
  bool usable = true;  // false: image or camera_info is unusable
  sensor_msgs::ImagePtr image;
  sensor_msgs::CameraInfoPtr info;
  std::string what;  // the defect, for messages
};

struct PairPlan {
  ros::Time stamp_a;
  Expect expect = Expect::kPublish;
  std::string why;
};

class BadInputScenario {
 public:
  BadInputScenario(const LinearRateMotion& motion, const RollingShutterTiming& timing,
                   const Eigen::Matrix3d& R_cam_imu, double max_imu_gap_s)
      : motion_(motion), timing_(timing), R_cam_imu_(R_cam_imu), max_imu_gap_s_(max_imu_gap_s) {
    buildSegment1();
    buildSegment2();
    planPairs(segment1_imu_, segment1_frames_);
    planPairs(segment2_imu_, segment2_frames_);
  }

  std::vector<StreamEvent> events() const {
    std::vector<StreamEvent> events;
    for (const auto* imu_plans : {&segment1_imu_, &segment2_imu_}) {
      for (const ImuPlan& plan : *imu_plans) {
        StreamEvent event;
        event.publish_key_s = plan.key_s;
        event.imu = makeImu(plan.stamp, plan.frame_id, plan.rate_rad_s);
        events.push_back(event);
      }
    }
    for (const auto* frame_plans : {&segment1_frames_, &segment2_frames_}) {
      for (const FramePlan& plan : *frame_plans) {
        StreamEvent event;
        event.publish_key_s = plan.key_s;
        event.image = plan.image;
        event.info = plan.info;
        events.push_back(event);
      }
    }
    sortByPublishKey(events);
    return events;
  }

  // Frame pairs by the later frame's stamp.
  const std::map<ros::Time, PairPlan>& pairs() const { return pairs_; }
  // The defect of a frame that must be ignored, empty for other stamps.
  std::string defectAt(const ros::Time& stamp) const {
    const auto defect = defects_.find(stamp);
    return defect == defects_.end() ? std::string() : defect->second;
  }
  ros::Time lastStamp() const { return segment2_frames_.back().stamp; }

 private:
  ros::Time frameStamp(int j) const { return motion_.reference_stamp + ros::Duration(0.1 + j * kFramePeriodS); }
  double frameTau(int j) const { return motion_.tau(frameStamp(j)); }

  // A good frame at `stamp` published at stream time `key_s`.
  static FramePlan goodFrame(const ros::Time& stamp, double key_s) {
    FramePlan plan;
    plan.stamp = stamp;
    plan.key_s = key_s;
    plan.image = makeImage(stamp, kImageWidthPx, kImageHeightPx);
    plan.info = makeInfo(stamp);
    return plan;
  }

  // Good IMU samples every 2.5 ms over [tau_begin_s, tau_end_s], published kImuLeadS early.
  std::vector<ImuPlan> goodImu(double tau_begin_s, double tau_end_s, double key_shift_s) const {
    std::vector<ImuPlan> plans;
    const int64_t first = static_cast<int64_t>(std::ceil(tau_begin_s / kImuPeriodS));
    for (int64_t k = first; k * kImuPeriodS <= tau_end_s; ++k) {
      ImuPlan plan;
      plan.stamp = motion_.reference_stamp + ros::Duration(0, 2500000) * static_cast<double>(k);
      plan.key_s = motion_.tau(plan.stamp) - kImuLeadS + key_shift_s;
      plan.rate_rad_s = R_cam_imu_.transpose() * motion_.cameraRate(motion_.tau(plan.stamp));
      plans.push_back(plan);
    }
    return plans;
  }

  // Index of the first sample at or after `tau_s`.
  static std::size_t sampleAt(const std::vector<ImuPlan>& plans, const LinearRateMotion& motion, double tau_s) {
    std::size_t k = 0;
    while (k < plans.size() && motion.tau(plans[k].stamp) < tau_s) ++k;
    return k;
  }

  void buildSegment1() {
    std::vector<ImuPlan> imu = goodImu(0.0, frameTau(kSegment1Frames - 1) + 0.1, 0.0);
    std::vector<ImuPlan> extra;  // messages added to the clean stream

    // (a) 25 non-finite samples in a row (62.5 ms: a hole wider than max_imu_gap), then a single
    // one, which leaves a 5 ms hole that linear interpolation bridges exactly.
    const std::size_t nan_start = sampleAt(imu, motion_, frameTau(10) + 0.004);
    for (std::size_t k = nan_start; k < nan_start + 25; ++k) {
      Eigen::Vector3d& rate = imu[k].rate_rad_s;
      switch (k % 3) {
        case 0: rate.setConstant(std::nan("")); break;
        case 1: rate.x() = std::nan(""); break;
        default: rate.z() = INFINITY; break;
      }
      imu[k].usable = false;
    }
    const std::size_t single_nan = sampleAt(imu, motion_, frameTau(17) + 0.01);
    imu[single_nan].rate_rad_s.y() = std::nan("");
    imu[single_nan].usable = false;

    // (b) Eight samples published newest first: only the first one out is usable (20 ms hole).
    // Their rates are genuine, so inserting them in order would be correct too.
    const std::size_t reversed_start = sampleAt(imu, motion_, frameTau(24) + 0.003);
    for (std::size_t m = 0; m < 8; ++m) {
      ImuPlan& plan = imu[reversed_start + m];
      plan.key_s = imu[reversed_start + 7].key_s + (7 - m) * 1e-5;
      plan.usable = (m == 7);
    }
    // Duplicates sent after the original: a repeat with the same content and, worse, repeats
    // carrying wrong rates, which would visibly bend the homographies if they replaced the
    // original.
    for (double tau_s : {frameTau(28) + 0.001, frameTau(29) + 0.012, frameTau(30) + 0.02}) {
      const ImuPlan& original = imu[sampleAt(imu, motion_, tau_s)];
      ImuPlan duplicate = original;
      duplicate.key_s += 1e-5;
      duplicate.rate_rad_s += Eigen::Vector3d(3.0, -3.0, 3.0);
      duplicate.usable = false;
      extra.push_back(duplicate);
    }
    ImuPlan repeat = imu[sampleAt(imu, motion_, frameTau(31))];
    repeat.key_s += 1e-5;
    repeat.usable = false;
    extra.push_back(repeat);

    // (c) No IMU samples for 300 ms.
    const double gap_begin_tau_s = frameTau(38) + 0.003;
    imu.erase(std::remove_if(imu.begin(), imu.end(),
                             [&](const ImuPlan& plan) {
                               const double tau = motion_.tau(plan.stamp);
                               return tau >= gap_begin_tau_s && tau < gap_begin_tau_s + 0.3;
                             }),
              imu.end());

    // (g) 150 ms of samples in a frame tf does not know, their rates expressed in that frame (the
    // IMU frame turned 90 deg about z): using them as imu_link rates would bend the homographies.
    const Eigen::Matrix3d R_untracked_imu =
        Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const double untracked_begin_tau_s = frameTau(100) + 0.01;
    for (ImuPlan& plan : imu) {
      const double tau = motion_.tau(plan.stamp);
      if (tau >= untracked_begin_tau_s && tau <= untracked_begin_tau_s + 0.15) {
        plan.frame_id = kUntrackedImuFrame;
        plan.rate_rad_s = R_untracked_imu * plan.rate_rad_s;
        plan.untracked = true;
        plan.usable = false;
      }
    }
    imu.insert(imu.end(), extra.begin(), extra.end());
    segment1_imu_ = imu;

    for (int j = 0; j < kSegment1Frames; ++j) {
      FramePlan frame = goodFrame(frameStamp(j), frameTau(j));
      // (d) unusable images, (e) a camera_info with K all zeros.
      if (j == 60) {
        frame.image = makeImage(frame.stamp, kImageWidthPx, kImageHeightPx, "not_an_encoding");
        frame.what = "(d) encoding 'not_an_encoding'";
      } else if (j == 63) {
        frame.image = makeImage(frame.stamp, 0, 0);
        frame.what = "(d) zero-size image";
      } else if (j == 66) {
        frame.image = makeImage(frame.stamp, kImageWidthPx / 2, kImageHeightPx / 2);
        frame.what = "(d) image smaller than camera_info says";
      } else if (j == 75 || j == 76) {
        std::fill(frame.info->K.begin(), frame.info->K.end(), 0.0);
        std::fill(frame.info->P.begin(), frame.info->P.end(), 0.0);
        frame.what = "(e) camera_info K all zeros";
      }
      frame.usable = frame.what.empty();
      segment1_frames_.push_back(frame);
      // (f) a frame sent twice, and frames older than the latest one. They go out a third of a
      // frame period apart: sent back to back, the image + camera_info synchronizer would merge
      // or discard them before the nodelet's own checks see them.
      if (j == 85) {
        FramePlan duplicate = goodFrame(frame.stamp, frame.key_s + kFramePeriodS / 3);
        duplicate.what = "(f) duplicate camera stamp";
        segment1_frames_.push_back(duplicate);
      } else if (j == 90) {
        int n = 1;
        for (double back_s : {0.5 * kFramePeriodS, 0.47}) {
          FramePlan old = goodFrame(frame.stamp - ros::Duration(back_s), frame.key_s + n++ * kFramePeriodS / 3);
          old.what = "(f) out-of-order camera stamp";
          segment1_frames_.push_back(old);
        }
      }
    }
  }

  // (h) The stream continues 10 s in the past after a pause, as a looping bag player does.
  void buildSegment2() {
    const double key_shift_s = kLoopJumpS + kLoopPauseKeyS;
    const double first_tau_s = frameTau(kSegment1Frames) - kLoopJumpS;
    segment2_imu_ = goodImu(first_tau_s - 0.1, first_tau_s + kSegment2Frames * kFramePeriodS + 0.1, key_shift_s);
    for (int j = kSegment1Frames; j < kSegment1Frames + kSegment2Frames; ++j) {
      const ros::Time stamp = frameStamp(j) - ros::Duration(kLoopJumpS);
      segment2_frames_.push_back(goodFrame(stamp, motion_.tau(stamp) + key_shift_s));
    }
  }

  // Whether the usable samples bracket [begin, end] and are nowhere further apart than the gap.
  bool computable(const std::vector<double>& usable_taus, double begin_s, double end_s) const {
    if (usable_taus.empty() || usable_taus.front() > begin_s || usable_taus.back() < end_s) return false;
    auto first = std::upper_bound(usable_taus.begin(), usable_taus.end(), begin_s) - 1;
    const auto last = std::lower_bound(usable_taus.begin(), usable_taus.end(), end_s);
    for (; first != last; ++first) {
      if (*(first + 1) - *first > max_imu_gap_s_) return false;
    }
    return true;
  }

  void planPairs(const std::vector<ImuPlan>& imu, std::vector<FramePlan> frames) {
    std::vector<double> usable_taus, untracked_taus;
    for (const ImuPlan& plan : imu) {
      if (plan.usable) usable_taus.push_back(motion_.tau(plan.stamp));
      if (plan.untracked) untracked_taus.push_back(motion_.tau(plan.stamp));
    }
    std::sort(usable_taus.begin(), usable_taus.end());
    std::stable_sort(frames.begin(), frames.end(),
                     [](const FramePlan& a, const FramePlan& b) { return a.key_s < b.key_s; });
    const FramePlan* previous = nullptr;
    for (const FramePlan& frame : frames) {
      if (!frame.usable || (previous != nullptr && frame.stamp <= previous->stamp)) {
        if (!frame.what.empty()) defects_[frame.stamp] += frame.what + "; ";
        continue;
      }
      if (previous != nullptr) {
        PairPlan pair;
        pair.stamp_a = previous->stamp;
        const auto [begin_s, end_s] = timing_.imuInterval(motion_, previous->stamp, frame.stamp);
        std::ostringstream why;
        why << "pair [" << motion_.tau(previous->stamp) << ", " << motion_.tau(frame.stamp)
            << "] s after the reference, IMU [" << begin_s << ", " << end_s << "] s";
        if (!computable(usable_taus, begin_s, end_s)) {
          pair.expect = Expect::kSilent;
          why << ": usable IMU samples do not cover it";
        } else {
          // The nodelet may judge the IMU frame by a message newer than the pair's samples (IMU
          // runs ahead of the frames, by more when the frame is delivered late): a pair just
          // before (g) may go either way.
          const double latest_tau_s = motion_.tau(frame.stamp) + kImuLeadS + kDeliveryJitterS;
          for (double tau : untracked_taus) {
            if (tau >= end_s && tau <= latest_tau_s) {
              pair.expect = Expect::kEither;
              why << ": IMU messages right after it are in an untracked frame";
              break;
            }
          }
        }
        pair.why = why.str();
        pairs_[frame.stamp] = pair;
      }
      previous = &frame;
    }
  }

  const LinearRateMotion motion_;
  const RollingShutterTiming timing_;
  const Eigen::Matrix3d R_cam_imu_;
  const double max_imu_gap_s_;
  std::vector<ImuPlan> segment1_imu_, segment2_imu_;
  std::vector<FramePlan> segment1_frames_, segment2_frames_;
  std::map<ros::Time, PairPlan> pairs_;
  std::map<ros::Time, std::string> defects_;
};

TEST(GyroFlowBadInput, PublishesExactlyThePairsTheInputSupports) {
  RollingShutterTiming timing;
  ASSERT_TRUE(readTiming(timing));
  int grid_width_px = 0, grid_height_px = 0;
  ASSERT_TRUE(readGridSize(grid_width_px, grid_height_px));
  double max_imu_gap_s = 0.0;
  ASSERT_TRUE(ros::param::get(std::string(kNodeletNamespace) + "/max_imu_gap", max_imu_gap_s));

  const Eigen::Matrix3d R_cam_imu = syntheticImuToCamera();
  const Eigen::Matrix3d K = syntheticK();
  LinearRateMotion motion;
  motion.reference_stamp = ros::Time(1000, 0);
  motion.pan_acceleration_rad_s2 = 0.4;  // the stream is 6 s long: keep the rates moderate
  const BadInputScenario scenario(motion, timing, R_cam_imu, max_imu_gap_s);

  GyroFlowHarness harness(/*subscribe_color=*/false);
  harness.publishStaticTransform(R_cam_imu);
  ASSERT_TRUE(harness.waitForNodelet(30.0));
  harness.play(scenario.events(), kPlaybackSpeed);

  // The last frames come after the loop: their GyroFlow shows the nodelet survived and reset.
  const ros::Time last_stamp = scenario.lastStamp();
  EXPECT_TRUE(harness.waitForFlows(
      [&](const std::vector<GyroFlowConstPtr>& flows) {
        return !flows.empty() && flows.back()->header.stamp == last_stamp;
      },
      5.0))
      << "no GyroFlow for the last frame after the loop (" << last_stamp << ")";

  const std::map<ros::Time, PairPlan>& pairs = scenario.pairs();
  std::map<ros::Time, int> received_count;
  int checked_homographies = 0;
  for (const GyroFlowConstPtr& msg : harness.flows()) {
    const ros::Time stamp = msg->header.stamp;
    ++received_count[stamp];
    const auto pair = pairs.find(stamp);
    if (pair == pairs.end()) {
      ADD_FAILURE() << "GyroFlow " << stamp << " (previous " << msg->previous_stamp
                    << ") does not end a pair of usable frames " << scenario.defectAt(stamp);
      continue;
    }
    SCOPED_TRACE("GyroFlow " + std::to_string(stamp.toSec()) + ", " + pair->second.why);
    EXPECT_NE(pair->second.expect, Expect::kSilent) << "published although it must not be";
    EXPECT_TRUE(metadataAndFlowMatch(*msg, pair->second.stamp_a, timing, K, R_cam_imu, grid_width_px,
                                     grid_height_px));
    EXPECT_TRUE(homographiesMatch(expectedHomographies(motion, timing, K, pair->second.stamp_a, stamp),
                                  homographiesOf(*msg)));
    ++checked_homographies;
  }
  std::map<Expect, int> planned, published;
  for (const auto& [stamp, pair] : pairs) {
    ++planned[pair.expect];
    const int count = received_count.count(stamp) ? received_count.at(stamp) : 0;
    published[pair.expect] += count > 0;
    EXPECT_LE(count, 1) << "GyroFlow " << stamp << " published " << count << " times";
    if (pair.expect == Expect::kPublish) {
      EXPECT_EQ(count, 1) << "no GyroFlow for frame " << stamp << ", " << pair.why;
    } else {
      // The pairs the bad input affects, for whoever reads the log of a failure.
      std::cout << "[ INFO     ] " << toString(pair.expect) << ", " << (count > 0 ? "published" : "silent")
                << ": " << pair.why << "\n";
    }
  }
  for (Expect expect : {Expect::kPublish, Expect::kSilent, Expect::kEither}) {
    std::cout << "[ INFO     ] " << toString(expect) << ": " << planned[expect] << " pairs, "
              << published[expect] << " published\n";
  }
  // Sanity of the scenario itself: every phase leaves pairs of each kind to check.
  EXPECT_GT(planned[Expect::kPublish], 100);
  EXPECT_GT(planned[Expect::kSilent], 15);
  EXPECT_GT(checked_homographies, 100);
}

}  // namespace
}  // namespace deep_ois

int main(int argc, char** argv) {
  return deep_ois::rostest_helpers::runRostestGtests(argc, argv, "test_gyro_flow_bad_input");
}
