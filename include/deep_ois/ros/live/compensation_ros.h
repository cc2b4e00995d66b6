// ROS wrapper of the compensation network: for every gyro flow, the OIS-compensated flow and
// frame a warped onto frame b.
#pragma once

#include <deep_ois/GyroFlow.h>
#include <image_transport/image_transport.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>

#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>
#include <string>

#include "deep_ois/core/flow/backward_map.h"
#include "deep_ois/core/flow/patch_homography_map.h"
#include "deep_ois/core/common/drop_tally.h"
#include "deep_ois/core/common/output_shedding.h"
#include "deep_ois/core/common/stamp_clock_check.h"
#include "deep_ois/core/ois/compensation_method.h"
#include "deep_ois/core/flow/flow_frame_matcher.h"
#include "deep_ois/net/compensation_model.h"
#include "deep_ois/net/compensation_stream.h"
#include "deep_ois/ros/live/compensation_parameters.h"
#include "deep_ois/ros/live/compensation_reconfigure.h"
#include "deep_ois/ros/live/stabiliser_flow_compensator.h"
#include "deep_ois/ros/live/flow_image_publisher.h"
#include "deep_ois/ros/live/live_diagnostics.h"
#include "deep_ois/ros/live/online_learning_ros.h"

namespace deep_ois {


// Topics (relative to the node handle): subscribes `gyro_flow` (deep_ois/GyroFlow) and
// `image_raw` (image_transport); publishes `compensated_flow` (deep_ois/GyroFlow: the gyro
// message with the flow replaced by the network's), `compensated_flow/color` (rgb8),
// `aligned/image_raw` (frame a warped onto frame b by the compensated flow, frame b's stamp and
// frame a's encoding) and `aligned/ghost` (rgb8: red of frame b over green/blue of the aligned
// frame a). Inputs are subscribed only while an output has a subscriber (compensation_check
// included); each output is computed only while it has one. Every field of an input GyroFlow is
// validated before use, and every published GyroFlow before it goes out (message_validation.h).
//
// The gyro flows are one camera's consecutive pairs: the model sees each with the motion history
// of the earlier ones (CompensationStream); a gap (a pair never received, a bag that loops)
// restarts the history, as at start-up.
//
// With a stabiliser model, each pair is also checked against the images and learned from
// (OnlineLearningRos: `compensation_check`, the fallback to the plain gyro, the model swapped when
// a better one is learned; docs/online_learning.md).
//
// Threading: callbacks run on the node handle's queue; one mutex guards the state. The network
// runs inside the callback (a few ms with the fast preset); the online learning's tracking and
// fits run in its own threads and never block a callback.
class CompensationRos {
 public:
  // Loads the model; throws ModelFileError naming the file and the problem, or
  // std::invalid_argument for a bad parameter.
  //
  // Reliability: no exception leaves a callback (each is caught at the callback, counted, and
  // said in a throttled warning naming the topic); every gyro flow not turned into an output is
  // counted by reason and said in one throttled warning (FlowFrameMatcher decides per flow, so a
  // lost frame costs only the flows that need it).
  CompensationRos(ros::NodeHandle nh, ros::NodeHandle private_nh);
  ~CompensationRos();

  CompensationRos(const CompensationRos&) = delete;
  CompensationRos& operator=(const CompensationRos&) = delete;

 private:
  using Matcher = FlowFrameMatcher<GyroFlowConstPtr, sensor_msgs::ImageConstPtr>;

  // The motion a method made for one pair: the flow on the gyro flow's grid, and the per-patch
  // homographies in `camera` when the method has them (empty: the message keeps the input's).
  struct CompensatedMotion {
    cv::Mat flow;
    std::vector<Eigen::Matrix3d> homographies;
    CameraModel camera;
  };

  void connectCallback();
  // Subscribes the inputs while an output (compensation_check included) has a subscriber, and
  // unsubscribes when none has. mutex_ held.
  void updateSubscriptions();
  void gyroFlowCallback(const GyroFlowConstPtr& msg);
  void imageCallback(const sensor_msgs::ImageConstPtr& msg);
  void expireTimerCallback(const ros::WallTimerEvent&);
  // Runs `handle` and turns any exception into a counted, throttled warning naming `topic`.
  template <typename Handle>
  void guarded(const std::string& topic, Handle handle);
  // Processes the matched flows and accounts for the dropped ones (their motion still enters the
  // history of the next pairs), in stamp order.
  void settle(const std::vector<Matcher::Settled>& settled);
  // Counts a gyro flow that got no output (the throttled warning and /diagnostics).
  void countDrop(const std::string& reason);
  // Adds the flow's motion to the history without an output.
  void observeOnly(const GyroFlow& gyro);
  // Says once that the stabiliser model restarted because time went back by `back_s` (> 0).
  void sayTimeJump(const GyroFlow& gyro, double back_s);
  // Says (once per change, and in /diagnostics) that the flows' calibration changed and the
  // stabiliser model carried its state across it (GyroFlow.calibration_epoch).
  void sayCalibrationChange(const GyroFlow& gyro);
  // Says (throttled, and in /diagnostics) what is shed under overload now that the shedding level
  // moved from `shed_before` outputs; `lag_s`: the pair's lag that moved it.
  void sayShedding(double lag_s, std::size_t shed_before);
  // Processing delay of the pair ending at `stamp_b` beyond the smallest seen, seconds.
  double lagS(const ros::Time& stamp_b);
  // The throttled warning of everything dropped since the last one.
  void reportDrops();
  void process(const GyroFlow& gyro, const sensor_msgs::ImageConstPtr& image_a,
               const sensor_msgs::ImageConstPtr& image_b);
  // The three methods (compensation_method.h chooses): each returns the motion to publish, or
  // nothing after counting and saying why. `gyro_flow` views the message's flow.
  std::optional<CompensatedMotion> asMeasured(const GyroFlow& gyro, const cv::Mat& gyro_flow);
  std::optional<CompensatedMotion> withStabiliserModel(const GyroFlow& gyro, const sensor_msgs::ImageConstPtr& image_a,
                                                       const sensor_msgs::ImageConstPtr& image_b,
                                                       const std::vector<Eigen::Matrix3d>& gyro_homographies,
                                                       const cv::Mat& gyro_flow);
  // ~fusion: the pair's tracks (frames at ~learning_tracking_width) into `tracks` and the fusion's
  // inputs; none (counted, said) when the frames cannot be tracked. Timed for /diagnostics.
  std::optional<PairFusion> fusionFor(const sensor_msgs::ImageConstPtr& image_a,
                                      const sensor_msgs::ImageConstPtr& image_b, std::vector<FeatureMatch>& tracks);
  // Counts a fused pair (refined or prior kept) and updates its /diagnostics.
  void countFusion(const StabiliserFlowResult& result, double compensate_s);
  std::optional<CompensatedMotion> withNetwork(const GyroFlow& gyro, const cv::Mat& gyro_flow);
  // Says once (per timeline) when the stamps on `topic` are far from ROS time (use_sim_time).
  void checkStampClock(const ros::Time& stamp, const std::string& topic);
  bool anyOutputWanted() const;
  // The model's camera (either kind) against the flow's (once per camera); false when it differs
  // and ~require_matching_camera refuses it (the flow is then counted as dropped).
  bool checkModelCamera(const GyroFlow& gyro);
  const CameraDescription& modelCamera() const;

  ros::NodeHandle nh_;
  ros::NodeHandle private_nh_;
  // The nodelet's resolved name (e.g. /deep_ois/gyro_flow), first in every log line: two cameras
  // in one manager are told apart.
  std::string log_name_;
  // Its live-tunable fields change (under mutex_) through dynamic_reconfigure.
  CompensationParameters params_;
  CompensatorKind compensator_kind_;  // from ~model, once
  // Exactly one of: the network over the camera's pairs with their motion history, or the learned
  // stabiliser model carrying the stabiliser's state on the gyro stream.
  std::unique_ptr<CompensationModel> model_;
  std::unique_ptr<CompensationStream> stream_;
  std::unique_ptr<StabiliserFlowCompensator> stabiliser_;
  // With a stabiliser model: the per-pair checks, the fallback and the online learning.
  std::unique_ptr<OnlineLearningRos> learning_;
  // ~fusion: the tracker (the learner's options) and the counts for /diagnostics.
  FeatureTracker fusion_tracker_{OnlineLearningOptions::learningCorners(), OnlineLearningOptions::learningKlt()};
  FusionOptions fusion_options_;
  struct FusionCounts {
    std::size_t pairs = 0, refined = 0, failed = 0, untracked = 0;
    double correction_sum_px = 0.0;       // over the refined pairs
    double tracking_s = 0.0, compensate_s = 0.0;  // wall time, summed over the fused pairs
  } fusion_counts_;
  // The model's camera against the stream's, checked on the first flow (and when the camera
  // changes): empty when they match, else the difference.
  std::string camera_check_;
  std::string checked_camera_;  // summary of the camera last checked

  std::mutex mutex_;
  image_transport::ImageTransport it_;
  ros::Subscriber gyro_flow_sub_;
  image_transport::Subscriber image_sub_;
  ros::Publisher compensated_pub_;
  image_transport::Publisher color_pub_;
  image_transport::Publisher aligned_pub_;
  image_transport::Publisher ghost_pub_;
  FlowImagePublisher flow_image_pub_;  // compensated_flow/image: the flow as a plain 32FC2 image

  FixedPointMap warp_map_;
  // Builds warp_map_ from a stabiliser model's per-patch homographies (per camera).
  std::unique_ptr<PatchHomographyMapBuilder> patch_map_builder_;  // the backward map of the current pair (buffers reused per frame)
  ros::WallTimer expire_timer_;

  Matcher matcher_;
  DropTally drops_;                  // gyro flows without an output, by reason
  // Graceful overload: the optional outputs (colour, aligned frame, ghost) left out of late pairs,
  // costliest first by their measured wall time, before a pair is dropped by ~max_lag.
  OutputShedding shedding_;
  ros::WallTime last_drop_report_;
  std::optional<ros::Time> last_flow_stamp_;  // frame b of the last gyro flow received
  std::optional<double> min_delay_s_;         // smallest handling delay seen (see ~max_lag)
  std::optional<cv::Size> last_flow_grid_;    // the history restarts when the grid changes
  StampClockCheck stamp_clock_;               // input stamps against ROS time
  std::size_t errors_ = 0;  // exceptions caught at the callbacks
  std::size_t published_ = 0;
  int calibration_changes_said_ = 0, calibration_restarts_said_ = 0;  // stabiliser model, said so far
  std::size_t ghosts_not_drawn_ = 0;  // pairs with an output whose ghost could not be drawn
  std::unique_ptr<LiveDiagnostics> diagnostics_;  // /diagnostics: rates, drops, latency, model
  std::unique_ptr<CompensationReconfigure> reconfigure_;
};

}  // namespace deep_ois
