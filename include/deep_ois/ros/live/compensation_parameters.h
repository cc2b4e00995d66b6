// Every parameter of the compensation wrapper, read and validated in one place. Torch-free, so the
// parameter table can be checked (test_parameter_docs) in a build without libtorch.
#pragma once

#include <ros/node_handle.h>

#include <string>

#include "deep_ois/core/vision/live_tracking.h"
#include "deep_ois/ros/live/parameter_source.h"

namespace deep_ois {

struct CompensationParameters {
  // ~model: the model file (required): a network (.pt) or a learned stabiliser model (.yaml,
  // train_stabiliser), which predicts the lens from the gyro stream with the stabiliser's state.
  std::string model_path;
  // ~require_matching_camera: a model (either kind) trained for another camera (size, K, and the
  // readout when the model records it) is refused instead of warned about.
  bool require_matching_camera = false;
  int torch_threads = 1;         // ~torch_threads: intra-op threads (process-wide in torch)
  // Input queues hold a second of 30 fps video: work is dropped by ~max_lag, counted and said,
  // rather than silently by a full subscriber queue.
  int image_queue_size = 30;      // ~image_queue_size
  int gyro_flow_queue_size = 30;  // ~gyro_flow_queue_size
  int image_cache_size = 30;     // ~image_cache_size: frames kept to pair with gyro flows
  double max_wait_s = 1.0;       // ~max_wait: wall time a gyro flow waits for its images
  int max_pending_flows = 60;    // ~max_pending_flows: gyro flows waiting for their frames
  // ~max_image_pixels: larger frames are refused (3840x2160, 4K UHD: the largest common video
  // mode; 30 cached rgb8 frames of it take 750 MB, and the network works at 360x270 anyway).
  int max_image_pixels = 3840 * 2160;
  // ~max_lag: a pair whose frame b is this much later (ROS time of handling minus stamp, above
  // the smallest such delay seen, which absorbs a constant clock offset) is dropped unprocessed:
  // the compensation catches up instead of falling behind.
  double max_lag_s = 0.5;
  // ~test_processing_delay: TEST HOOK ONLY (default 0): seconds slept per processed pair, to
  // make a slow compensation in the lag rostest on any machine. Never set it in use.
  double test_processing_delay_s = 0.0;
  int warp_iterations = 3;       // ~warp_iterations: fixed-point steps inverting the flow
  int warp_threads = 1;          // ~warp_threads: OpenCV threads for the warp (process-wide)
  double color_max_flow_px = 0.0;  // ~color_max_flow: as the gyro flow nodelet's

  // Online self-calibration of a stabiliser model (core/online/online_stabiliser_learner.h); the
  // per-pair check (compensation_check) and the fallback to the plain gyro run whenever a
  // stabiliser model is in use.
  bool learning = true;             // ~learning: learn the camera's stabiliser while running
  // ~learning_key: names this camera's learned model file; empty = from the stream (frame id,
  // size and focal length), so a swapped camera gets its own.
  std::string learning_key;
  // ~learning_dir: where learned models are kept; empty = $ROS_HOME/deep_ois/stabilisers
  // (~/.ros/deep_ois/stabilisers).
  std::string learning_dir;
  double learning_cpu_share = 0.3;  // ~learning_cpu_share: of one core, tracking and fits together
  int learning_tracking_width_px = kLiveTrackingWidthPx;  // ~learning_tracking_width: frames tracked at most this wide
  double learning_buffer_s = 40.0;       // ~learning_buffer: seconds of motion-rich windows kept
  double learning_held_out_s = 6.0;      // ~learning_held_out: newest seconds the swap is decided on
  double learning_refit_every_s = 4.0;   // ~learning_refit_every: new seconds between fits
  // ~learning_rls: recursive least squares with forgetting on the linear-dynamics stage's
  // coefficients between the fits (core/ois/linear_dynamics_rls.h); its forgetting factor per
  // second (~learning_rls_forgetting) and its start's worth in lens motions (~learning_rls_prior).
  bool learning_rls = true;
  double learning_rls_forgetting = 0.98;
  double learning_rls_prior = 20.0;
  // ~learning_confirm_pairs: usable pairs the per-pair check scores a swap on before it is
  // confirmed (and written) or undone
  int learning_confirm_pairs = 60;
  // ~learning_test_write_pause: test hook, seconds the write of a confirmed model pauses halfway
  // (a test kills the process during it); 0 in normal use
  double learning_test_write_pause_s = 0.0;
  bool fallback_to_gyro = true;          // ~fallback_to_gyro: publish the plain gyro while the model does worse
  // ~fusion: a stabiliser model's motion refined per pair by the pair's tracks (core/fusion/
  // fused_motion.h; docs/fusion.md). Off by default: the output stays the model's.
  bool fusion = false;

  // Online camera-IMU calibration (core/online/online_calibration_estimator.h, fed from the
  // learner's tracks; ros/live/online_calibration_ros.h). ~online_calibration: on by default, so a
  // new camera needs no `calibrate` (a calibration is applied only when confidently better on
  // held-out pairs, and kept only once the per-pair check confirms it); needs a stabiliser model.
  bool online_calibration = true;
  // ~online_calibration_mount: also search the mount (24 signed axis permutations, then a small
  // rotation); off by default: the tf or ~imu_to_camera_rotation mount is held (a robot's is known).
  bool online_calibration_mount = false;
  // ~online_calibration_cpu_share: the estimator's own budget, a share of one core (its fits run on
  // the learner's tracking thread and count in ~learning_cpu_share too).
  double online_calibration_cpu_share = 0.12;
  // ~online_calibration_gyro_flow: the gyro flow nodelet's name relative to this node's namespace,
  // whose ~gyro_bias is the starting bias (its messages do not carry it).
  std::string online_calibration_gyro_flow = "gyro_flow";
};

// Reads every parameter with its default and checks it; throws std::invalid_argument naming the
// bad one. The nodelet reads its private namespace; tests and tools may read a YAML file of the
// same shape (config/compensation.yaml) through a YamlParameters source.
CompensationParameters loadCompensationParameters(const ParameterSource& source);
CompensationParameters loadCompensationParameters(const ros::NodeHandle& private_nh);

}  // namespace deep_ois
