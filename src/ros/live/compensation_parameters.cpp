#include "deep_ois/ros/live/compensation_parameters.h"

#include <cmath>
#include <stdexcept>

namespace deep_ois {

namespace {

void reject(const ParameterSource& nh, const std::string& name, const std::string& why) {
  throw std::invalid_argument("compensation: parameter " + nh.describe(name) + " " + why);
}
}  // namespace

CompensationParameters loadCompensationParameters(const ros::NodeHandle& private_nh) {
  // Strict: a parameter set with the wrong type is an error naming it, not a silent default.
  return loadCompensationParameters(NodeHandleParameters(private_nh));
}

CompensationParameters loadCompensationParameters(const ParameterSource& nh) {
  CompensationParameters p;
  if (!nh.get("model", p.model_path) || p.model_path.empty()) {
    reject(nh, "model", "is not set: give the model file (e.g. $(find deep_ois)/models/stabiliser_generic.yaml)");
  }
  p.require_matching_camera = nh.param("require_matching_camera", p.require_matching_camera);
  p.torch_threads = nh.param("torch_threads", p.torch_threads);
  if (p.torch_threads < 1) reject(nh, "torch_threads", "must be at least 1");
  p.image_queue_size = nh.param("image_queue_size", p.image_queue_size);
  p.gyro_flow_queue_size = nh.param("gyro_flow_queue_size", p.gyro_flow_queue_size);
  if (p.image_queue_size < 1 || p.gyro_flow_queue_size < 1) {
    reject(nh, "image_queue_size/gyro_flow_queue_size", "must be at least 1");
  }
  p.image_cache_size = nh.param("image_cache_size", p.image_cache_size);
  if (p.image_cache_size < 2) reject(nh, "image_cache_size", "must be at least 2 (both frames of a pair)");
  p.max_wait_s = nh.param("max_wait", p.max_wait_s);
  if (!std::isfinite(p.max_wait_s) || p.max_wait_s < 0.0) reject(nh, "max_wait", "must be >= 0 seconds");
  p.max_pending_flows = nh.param("max_pending_flows", p.max_pending_flows);
  if (p.max_pending_flows < 1) reject(nh, "max_pending_flows", "must be at least 1");
  p.max_image_pixels = nh.param("max_image_pixels", p.max_image_pixels);
  if (p.max_image_pixels < 1) reject(nh, "max_image_pixels", "must be at least 1 pixel");
  p.max_lag_s = nh.param("max_lag", p.max_lag_s);
  if (!std::isfinite(p.max_lag_s) || p.max_lag_s <= 0.0) reject(nh, "max_lag", "must be > 0 seconds");
  p.test_processing_delay_s = nh.param("test_processing_delay", p.test_processing_delay_s);
  if (!std::isfinite(p.test_processing_delay_s) || p.test_processing_delay_s < 0.0) {
    reject(nh, "test_processing_delay", "must be >= 0 seconds (a test hook: leave it unset)");
  }
  p.warp_iterations = nh.param("warp_iterations", p.warp_iterations);
  if (p.warp_iterations < 0 || p.warp_iterations > 20) reject(nh, "warp_iterations", "must be in [0, 20]");
  p.warp_threads = nh.param("warp_threads", p.warp_threads);
  if (p.warp_threads < 1) reject(nh, "warp_threads", "must be at least 1");
  p.color_max_flow_px = nh.param("color_max_flow", p.color_max_flow_px);
  if (!std::isfinite(p.color_max_flow_px) || p.color_max_flow_px < 0.0) {
    reject(nh, "color_max_flow", "must be >= 0 pixels (0 = scale each frame by its largest flow)");
  }
  p.fusion = nh.param("fusion", p.fusion);
  p.learning = nh.param("learning", p.learning);
  p.learning_key = nh.param("learning_key", p.learning_key);
  p.learning_dir = nh.param("learning_dir", p.learning_dir);
  p.learning_cpu_share = nh.param("learning_cpu_share", p.learning_cpu_share);
  if (!(p.learning_cpu_share > 0.0 && p.learning_cpu_share <= 1.0))
    reject(nh, "learning_cpu_share", "must be in (0, 1] (a share of one core)");
  p.learning_tracking_width_px = nh.param("learning_tracking_width", p.learning_tracking_width_px);
  if (p.learning_tracking_width_px < 64) reject(nh, "learning_tracking_width", "must be at least 64 pixels");
  p.learning_buffer_s = nh.param("learning_buffer", p.learning_buffer_s);
  p.learning_held_out_s = nh.param("learning_held_out", p.learning_held_out_s);
  p.learning_refit_every_s = nh.param("learning_refit_every", p.learning_refit_every_s);
  if (!(p.learning_held_out_s >= 2.0)) reject(nh, "learning_held_out", "must be at least 2 seconds (one window)");
  if (!(p.learning_buffer_s >= 2.0 * p.learning_held_out_s))
    reject(nh, "learning_buffer", "must be at least twice ~learning_held_out (seconds held out and trained on)");
  if (!(p.learning_refit_every_s > 0.0)) reject(nh, "learning_refit_every", "must be > 0 seconds");
  p.learning_rls = nh.param("learning_rls", p.learning_rls);
  p.learning_rls_forgetting = nh.param("learning_rls_forgetting", p.learning_rls_forgetting);
  if (!(p.learning_rls_forgetting > 0.0 && p.learning_rls_forgetting <= 1.0))
    reject(nh, "learning_rls_forgetting", "must be in (0, 1] (the weight left to a lens motion one second old)");
  p.learning_rls_prior = nh.param("learning_rls_prior", p.learning_rls_prior);
  if (!(p.learning_rls_prior > 0.0) || !std::isfinite(p.learning_rls_prior))
    reject(nh, "learning_rls_prior", "must be > 0 lens motions");
  p.learning_confirm_pairs = nh.param("learning_confirm_pairs", p.learning_confirm_pairs);
  if (p.learning_confirm_pairs < 1) reject(nh, "learning_confirm_pairs", "must be at least 1 pair");
  p.learning_test_write_pause_s = nh.param("learning_test_write_pause", p.learning_test_write_pause_s);
  if (!(p.learning_test_write_pause_s >= 0.0 && p.learning_test_write_pause_s <= 60.0))
    reject(nh, "learning_test_write_pause", "must be in [0, 60] seconds (a test hook; 0 in normal use)");
  p.fallback_to_gyro = nh.param("fallback_to_gyro", p.fallback_to_gyro);
  p.online_calibration = nh.param("online_calibration", p.online_calibration);
  p.online_calibration_mount = nh.param("online_calibration_mount", p.online_calibration_mount);
  p.online_calibration_cpu_share = nh.param("online_calibration_cpu_share", p.online_calibration_cpu_share);
  if (!(p.online_calibration_cpu_share > 0.0 && p.online_calibration_cpu_share <= 1.0))
    reject(nh, "online_calibration_cpu_share", "must be in (0, 1] (a share of one core)");
  p.online_calibration_gyro_flow = nh.param("online_calibration_gyro_flow", p.online_calibration_gyro_flow);
  if (p.online_calibration_gyro_flow.empty())
    reject(nh, "online_calibration_gyro_flow", "must name the gyro flow nodelet (e.g. gyro_flow)");
  return p;
}

}  // namespace deep_ois
