#include "deep_ois/ros/live/online_calibration_ros.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/common/so3_and_statistics.h"
#include "deep_ois/core/online/atomic_file_write.h"
#include "deep_ois/core/online/online_calibration_delayed_feed.h"
#include "deep_ois/ros/live/parameter_source.h"

namespace deep_ois {
namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;
// Pairs' lens shifts kept for the tracking thread (it is at most ~10 pairs behind: its queue).
constexpr std::size_t kLensesKept = 120;
// /diagnostics figures every this many pairs (and at every change).
constexpr std::size_t kDiagnosticsEveryPairs = 15;

Eigen::Matrix3d rowMajor(const boost::array<double, 9>& values) {
  Eigen::Matrix3d M;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) M(r, c) = values[static_cast<std::size_t>(3 * r + c)];
  return M;
}

void toRowMajor(const Eigen::Matrix3d& M, boost::array<double, 9>& values) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) values[static_cast<std::size_t>(3 * r + c)] = M(r, c);
}

void toArray(const Eigen::Vector3d& v, boost::array<double, 3>& values) {
  for (int i = 0; i < 3; ++i) values[static_cast<std::size_t>(i)] = v(i);
}

std::string millis(double seconds) {
  char text[40];
  std::snprintf(text, sizeof text, "%.3f ms", 1e3 * seconds);
  return text;
}

}  // namespace

std::string onlineCalibrationPath(const std::string& learned_model_path) {
  std::string base = learned_model_path;
  const std::string suffix = ".yaml";
  if (base.size() > suffix.size() && base.compare(base.size() - suffix.size(), suffix.size(), suffix) == 0)
    base.resize(base.size() - suffix.size());
  return base + ".calibration.yaml";
}

CameraImuCalibration loadCalibrationParameters(const std::string& path) {
  const YamlParameters file(path);
  CameraImuCalibration c;
  std::vector<double> rotation, bias;
  if (!file.get("time_offset", c.time_offset_s) || !std::isfinite(c.time_offset_s))
    throw std::runtime_error(path + ": time_offset is missing or not a number of seconds");
  if (!file.get("readout_time", c.readout_time_s) || !(c.readout_time_s >= 0.0 && c.readout_time_s <= 1.0))
    throw std::runtime_error(path + ": readout_time is missing or not in [0, 1] s");
  if (!file.get("imu_to_camera_rotation", rotation) || rotation.size() != 9)
    throw std::runtime_error(path + ": imu_to_camera_rotation must hold 9 numbers (row-major R_cam_imu)");
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) c.imu_to_camera_rotation(r, k) = rotation[static_cast<std::size_t>(3 * r + k)];
  const Eigen::Matrix3d should_be_identity = c.imu_to_camera_rotation * c.imu_to_camera_rotation.transpose();
  if (!c.imu_to_camera_rotation.allFinite() || !should_be_identity.isApprox(Eigen::Matrix3d::Identity(), 1e-6) ||
      c.imu_to_camera_rotation.determinant() < 0.0)
    throw std::runtime_error(path + ": imu_to_camera_rotation is not a rotation");
  if (!file.get("gyro_bias", bias) || bias.size() != 3 || !std::isfinite(bias[0] + bias[1] + bias[2]))
    throw std::runtime_error(path + ": gyro_bias must hold 3 finite numbers in rad/s");
  c.gyro_bias_rad_s = Eigen::Vector3d(bias[0], bias[1], bias[2]);
  return c;
}

std::string onlineCalibrationYaml(const CameraImuCalibration& c, const std::string& note) {
  std::ostringstream out;
  const auto list = [&out](const double* v, int n) {
    out << "[";
    for (int i = 0; i < n; ++i) out << (i ? ", " : "") << v[i];
    out << "]";
  };
  Eigen::Matrix<double, 3, 3, Eigen::RowMajor> rotation = c.imu_to_camera_rotation;
  out << "# Camera-IMU calibration learned online by the deep_ois/compensation nodelet and confirmed by\n"
      << "# its per-pair check (docs/online_learning.md). " << note << "\n"
      << "# The gyro flow nodelet's parameters: it can also be given as calibration:= to the launch files.\n";
  out << std::fixed << std::setprecision(4) << "# 1-sigma: time offset " << 1e3 * c.time_offset_sigma_s
      << " ms, readout " << 1e3 * c.readout_time_sigma_s << " ms, gyro bias (" << c.gyro_bias_sigma_rad_s(0) << ", "
      << c.gyro_bias_sigma_rad_s(1) << ", " << c.gyro_bias_sigma_rad_s(2) << ") rad/s, rotation ("
      << kRadToDeg * c.rotation_sigma_rad(0) << ", " << kRadToDeg * c.rotation_sigma_rad(1) << ", "
      << kRadToDeg * c.rotation_sigma_rad(2) << ") deg\n";
  out << std::setprecision(15) << std::defaultfloat;
  out << "time_offset: " << c.time_offset_s << "\n"
      << "readout_time: " << c.readout_time_s << "\n"
      << "imu_to_camera_rotation: ";
  list(rotation.data(), 9);
  out << "\ngyro_bias: ";
  list(c.gyro_bias_rad_s.data(), 3);
  out << "\n";
  return out.str();
}

OnlineCalibrationRos::OnlineCalibrationRos(ros::NodeHandle nh, const CompensationParameters& params,
                                           LiveDiagnostics& diagnostics, const std::string& log_name)
    : nh_(nh), params_(params), diagnostics_(diagnostics), log_name_(log_name) {
  // Latched: the last message is the calibration in use (a gyro flow nodelet started later gets it).
  pub_ = nh_.advertise<OnlineCalibration>("online_calibration", 1, true);
  diagnostics_.setValue("online calibration", "on (waiting for the first tracked pair)");
}

void OnlineCalibrationRos::startFor(const std::string& calibration_path, const GyroFlow& gyro, bool lens_moves) {
  CameraImuCalibration start;
  std::string source;
  std::string problem;
  std::error_code ignored;
  if (std::filesystem::exists(calibration_path, ignored)) {
    try {
      start = loadCalibrationParameters(calibration_path);
      source = "the confirmed calibration kept for this camera (" + calibration_path + ")";
    } catch (const std::exception& e) {
      problem = e.what();
    }
  }
  if (source.empty()) {
    start.time_offset_s = gyro.time_offset;
    start.readout_time_s = gyro.readout_time;
    start.imu_to_camera_rotation = rowMajor(gyro.imu_to_camera_rotation);
    // The gyro flow's messages do not carry the bias it subtracts: its parameter does.
    std::vector<double> bias;
    const std::string bias_param = params_.online_calibration_gyro_flow + "/gyro_bias";
    if (nh_.getParam(bias_param, bias) && bias.size() == 3 && std::isfinite(bias[0] + bias[1] + bias[2]))
      start.gyro_bias_rad_s = Eigen::Vector3d(bias[0], bias[1], bias[2]);
    source = "the gyro flow's parameters";
  }
  if (!problem.empty()) {
    ROS_WARN_NAMED("compensation", "%s: the online calibration file %s cannot be read (%s): starting from the "
                   "gyro flow's parameters; it will be replaced when a calibration is confirmed",
                   log_name_.c_str(), calibration_path.c_str(), problem.c_str());
  }
  const int stale = removeStalePartialFiles(calibration_path);
  if (stale > 0)
    ROS_INFO_NAMED("compensation", "%s: removed %d partial file(s) beside %s left by a process killed while writing",
                   log_name_.c_str(), stale, calibration_path.c_str());
  ROS_INFO_NAMED("compensation", "%s: online calibration on (mount %s, %.0f %% of a core, %s); starting from %s: "
                 "time offset %s, readout %s", log_name_.c_str(),
                 params_.online_calibration_mount ? "searched" : "held", 100.0 * params_.online_calibration_cpu_share,
                 lens_moves ? "a lens shift per frame besides the model's" : "a fixed lens",
                 source.c_str(), millis(start.time_offset_s).c_str(), millis(start.readout_time_s).c_str());
  std::lock_guard<std::mutex> lock(snapshot_mutex_);
  path_ = calibration_path;
  start_ = start;
  start_source_ = source;
  lens_moves_ = lens_moves;
  ++camera_generation_;
  const std::uint64_t changes = snapshot_.changes, log_id = snapshot_.log_id;
  snapshot_ = Snapshot();
  snapshot_.changes = changes + 1;  // published at the next afterPair
  snapshot_.log_id = log_id;
  snapshot_.started = true;
  snapshot_.applied = start;
  snapshot_.status.in_use = start;
  snapshot_.status.estimate = start;
  snapshot_.confirmation = "start: " + source;
  lenses_.clear();
}

void OnlineCalibrationRos::rememberLens(const GyroFlow& gyro, const StabiliserFlowResult& result, bool falling_back) {
  if (!result.ok || falling_back || result.shift_a_px.empty() ||
      result.shift_a_px.size() != result.shift_b_px.size())
    return;
  PairLensShift lens;
  lens.stamp_b_s = gyro.header.stamp.toSec();
  lens.shift_a_px = result.shift_a_px;
  lens.shift_b_px = result.shift_b_px;
  std::lock_guard<std::mutex> lock(snapshot_mutex_);
  lenses_.push_back(std::move(lens));
  while (lenses_.size() > kLensesKept) lenses_.pop_front();
}

OnlineFramePair OnlineCalibrationRos::withoutLens(const OnlineFramePair& pair) const {
  PairLensShift lens;
  {
    std::lock_guard<std::mutex> lock(snapshot_mutex_);
    const auto it = std::find_if(lenses_.begin(), lenses_.end(),
                                 [&](const PairLensShift& l) { return l.stamp_b_s == pair.stamp_b_s; });
    // Not found: the plain gyro was published, no lens to remove.
    if (it == lenses_.end()) return lenslessPair(pair, nullptr);
    lens = *it;
  }
  return lenslessPair(pair, &lens);
}

void OnlineCalibrationRos::onTrackedPair(const OnlineFramePair& pair) {
  try {
    work(pair);
  } catch (const std::exception& e) {
    std::lock_guard<std::mutex> lock(snapshot_mutex_);
    snapshot_.last_log = std::string("online calibration: a pair could not be used: ") + e.what();
    ++snapshot_.log_id;
  } catch (...) {
    std::lock_guard<std::mutex> lock(snapshot_mutex_);
    snapshot_.last_log = "online calibration: a pair could not be used (unknown error)";
    ++snapshot_.log_id;
  }
}

void OnlineCalibrationRos::work(const OnlineFramePair& pair) {
  std::string path;
  CameraImuCalibration start;
  std::uint64_t generation = 0;
  bool lens_moves = true;
  {
    std::lock_guard<std::mutex> lock(snapshot_mutex_);
    if (!snapshot_.started) return;
    lens_moves = lens_moves_;
    path = path_;
    start = start_;
    generation = camera_generation_;
  }
  if (!session_ || generation != estimator_generation_) {
    OnlineCalibrationOptions options;
    options.estimate_rotation = params_.online_calibration_mount;
    options.cpu_share = params_.online_calibration_cpu_share;
    // The tracks lose the model's lens motion before they come in (withoutLens); what the model
    // gets wrong is left to a shift per frame when the lens may move.
    options.lens_shift = lens_moves ? LensShiftHandling::kPerFrameShift : LensShiftHandling::kNone;
    session_ = std::make_unique<OnlineCalibrationSession>(
        options, static_cast<std::size_t>(params_.learning_confirm_pairs), pair.camera, start,
        [path](const CameraImuCalibration& confirmed) {
          writeFileAtomically(path, onlineCalibrationYaml(confirmed, "Written when confirmed."));
        },
        path);
    estimator_generation_ = generation;
  }
  if (time_went_back_.exchange(false)) session_->restartTimeline();

  // The estimator's copy: no frames, the tracks without the lens the compensation used.
  const OnlineCalibrationSession::Outcome outcome = session_->addPair(withoutLens(pair));
  const OnlineCalibrationStatus& status = session_->status();
  const std::uint32_t applied_version = session_->appliedVersion();
  const std::size_t swaps_confirmed = session_->swapsConfirmed();
  std::lock_guard<std::mutex> lock(snapshot_mutex_);
  if (generation != camera_generation_) return;  // another camera started meanwhile
  const bool changed = status.fits != snapshot_.status.fits || status.state != snapshot_.status.state ||
                       applied_version != snapshot_.applied_version || status.candidates_scored !=
                       snapshot_.status.candidates_scored || swaps_confirmed != snapshot_.swaps_confirmed;
  snapshot_.status = status;
  snapshot_.applied = session_->inUse();
  snapshot_.applied_version = applied_version;
  if (!outcome.confirmation.empty()) snapshot_.confirmation = outcome.confirmation;
  snapshot_.swaps_undone = session_->swapsUndone();
  snapshot_.swaps_confirmed = swaps_confirmed;
  snapshot_.saves_failed = session_->savesFailed();
  snapshot_.pairs_dropped = session_->pairsDropped();
  snapshot_.pairs_repeated = session_->pairsRepeated();
  if (changed) ++snapshot_.changes;
  if (!outcome.log.empty()) {
    snapshot_.last_log = outcome.log;
    ++snapshot_.log_id;
  }
}

void OnlineCalibrationRos::afterPair(const GyroFlow& gyro) {
  Snapshot snapshot;
  {
    std::lock_guard<std::mutex> lock(snapshot_mutex_);
    snapshot = snapshot_;
  }
  if (!snapshot.started) return;
  ++pairs_;
  if (snapshot.log_id != logged_id_) {
    logged_id_ = snapshot.log_id;
    if (!snapshot.last_log.empty()) ROS_INFO_NAMED("compensation", "%s: %s", log_name_.c_str(), snapshot.last_log.c_str());
  }
  const bool changed = snapshot.changes != published_changes_;
  if (changed) {
    published_changes_ = snapshot.changes;
    publish(gyro, snapshot);
  }
  if (changed || pairs_ % kDiagnosticsEveryPairs == 0) updateDiagnostics(snapshot, gyro);
}

void OnlineCalibrationRos::publish(const GyroFlow& gyro, const Snapshot& s) {
  auto msg = boost::make_shared<OnlineCalibration>();
  msg->header.stamp = gyro.header.stamp;
  msg->header.frame_id = gyro.header.frame_id;
  msg->state = s.status.state;
  msg->version = s.applied_version;
  const CameraImuCalibration& a = s.applied;
  msg->time_offset = a.time_offset_s;
  msg->time_offset_rate = a.time_offset_rate;
  msg->time_offset_reference = ros::Time(std::max(a.time_offset_reference_s, 0.0));
  msg->readout_time = a.readout_time_s;
  toArray(a.gyro_bias_rad_s, msg->gyro_bias);
  toRowMajor(a.imu_to_camera_rotation, msg->imu_to_camera_rotation);
  msg->time_offset_sigma = a.time_offset_sigma_s;
  msg->readout_time_sigma = a.readout_time_sigma_s;
  toArray(a.gyro_bias_sigma_rad_s, msg->gyro_bias_sigma);
  toArray(a.rotation_sigma_rad, msg->rotation_sigma);
  msg->mount_estimated = params_.online_calibration_mount;
  const CameraImuCalibration& e = s.status.estimate;
  msg->estimate_time_offset = e.time_offset_s;
  msg->estimate_readout_time = e.readout_time_s;
  toArray(e.gyro_bias_rad_s, msg->estimate_gyro_bias);
  toRowMajor(e.imu_to_camera_rotation, msg->estimate_imu_to_camera_rotation);
  msg->estimate_time_offset_sigma = e.time_offset_sigma_s;
  msg->estimate_readout_time_sigma = e.readout_time_sigma_s;
  toArray(e.gyro_bias_sigma_rad_s, msg->estimate_gyro_bias_sigma);
  toArray(e.rotation_sigma_rad, msg->estimate_rotation_sigma);
  msg->confirmation = s.confirmation;
  msg->pairs = static_cast<std::uint32_t>(s.status.pairs);
  msg->pairs_without_tracks = static_cast<std::uint32_t>(s.status.pairs_without_tracks);
  msg->fits = static_cast<std::uint32_t>(s.status.fits);
  msg->fits_needing_motion = static_cast<std::uint32_t>(s.status.fits_needing_motion);
  msg->fits_rejected = static_cast<std::uint32_t>(s.status.fits_rejected);
  msg->jumps = static_cast<std::uint32_t>(s.status.jumps);
  msg->swaps = static_cast<std::uint32_t>(s.status.swaps);
  msg->swaps_undone = static_cast<std::uint32_t>(s.swaps_undone);
  msg->swaps_confirmed = static_cast<std::uint32_t>(s.swaps_confirmed);
  const bool compared = s.status.candidates_scored > 0;
  msg->held_out_in_use_residual = compared ? static_cast<float>(s.status.held_out_in_use_px) : NAN;
  msg->held_out_candidate_residual = compared ? static_cast<float>(s.status.held_out_candidate_px) : NAN;
  msg->last_reason = s.status.last_reason;
  pub_.publish(msg);
}

void OnlineCalibrationRos::updateDiagnostics(const Snapshot& s, const GyroFlow& gyro) {
  const CameraImuCalibration& a = s.applied;
  const CameraImuCalibration& e = s.status.estimate;
  char text[320];
  diagnostics_.setValue("online calibration", s.status.state + " (version " + std::to_string(s.applied_version) + ")");
  std::snprintf(text, sizeof text, "%.3f ms in use; estimate %.3f +- %.3f ms (1-sigma)", 1e3 * a.time_offset_s,
                1e3 * e.time_offset_s, 1e3 * e.time_offset_sigma_s);
  diagnostics_.setValue("online calibration: time offset", text);
  std::snprintf(text, sizeof text, "%.3f ms in use; estimate %.3f +- %.3f ms (1-sigma)", 1e3 * a.readout_time_s,
                1e3 * e.readout_time_s, 1e3 * e.readout_time_sigma_s);
  diagnostics_.setValue("online calibration: readout", text);
  std::snprintf(text, sizeof text,
                "(%.5f, %.5f, %.5f) rad/s in use; estimate (%.5f, %.5f, %.5f) +- (%.5f, %.5f, %.5f) rad/s (IMU frame)",
                a.gyro_bias_rad_s(0), a.gyro_bias_rad_s(1), a.gyro_bias_rad_s(2), e.gyro_bias_rad_s(0),
                e.gyro_bias_rad_s(1), e.gyro_bias_rad_s(2), e.gyro_bias_sigma_rad_s(0), e.gyro_bias_sigma_rad_s(1),
                e.gyro_bias_sigma_rad_s(2));
  diagnostics_.setValue("online calibration: gyro bias", text);
  if (params_.online_calibration_mount) {
    const double off_deg = kRadToDeg * logSO3(e.imu_to_camera_rotation * a.imu_to_camera_rotation.transpose()).norm();
    std::snprintf(text, sizeof text, "searched: %s; estimate %.2f deg from the one in use, 1-sigma (%.2f, %.2f, %.2f) deg",
                  s.status.mount_found ? "axis permutation found" : "axis permutation not found yet", off_deg,
                  kRadToDeg * e.rotation_sigma_rad(0), kRadToDeg * e.rotation_sigma_rad(1),
                  kRadToDeg * e.rotation_sigma_rad(2));
  } else {
    std::snprintf(text, sizeof text, "held (the gyro flow's tf or ~imu_to_camera_rotation; ~online_calibration_mount)");
  }
  diagnostics_.setValue("online calibration: mount", text);
  std::snprintf(text, sizeof text,
                "%zu pairs (%zu without tracks, %zu dropped: %zu repeats, the rest waiting when time went back), "
                "%zu fits (%zu needing motion, %zu rejected, %zu over budget), %zu jumps, %zu swaps (%zu undone, %zu "
                "confirmed)",
                s.status.pairs, s.status.pairs_without_tracks, s.pairs_dropped, s.pairs_repeated, s.status.fits,
                s.status.fits_needing_motion,
                s.status.fits_rejected, s.status.fits_over_budget, s.status.jumps, s.status.swaps, s.swaps_undone,
                s.swaps_confirmed);
  diagnostics_.setValue("online calibration: counts", text);
  diagnostics_.setValue("online calibration: confirmation", s.confirmation);
  if (!s.status.last_reason.empty()) diagnostics_.setValue("online calibration: last", s.status.last_reason);
  std::snprintf(text, sizeof text, "%.1f %% of a core on the stream's clock (budget %.0f %%)",
                s.status.stream_s > 0.0 ? 100.0 * s.status.cpu_s / s.status.stream_s : 0.0,
                100.0 * params_.online_calibration_cpu_share);
  diagnostics_.setValue("online calibration CPU", text);
  // The gyro flow takes a drifting calibration's line at frame b (its header stamp).
  const bool follows = std::abs(gyro.time_offset - a.timeOffsetAt(gyro.header.stamp.toSec())) < 1e-8 &&
                       std::abs(gyro.readout_time - a.readout_time_s) < 1e-9;
  std::snprintf(text, sizeof text, "not (yet): its time offset %.3f ms, readout %.3f ms (~follow_online_calibration)",
                1e3 * gyro.time_offset, 1e3 * gyro.readout_time);
  diagnostics_.setValue("online calibration: used by the gyro flow", follows ? "yes" : text);
  std::lock_guard<std::mutex> lock(snapshot_mutex_);
  diagnostics_.setValue("online calibration file", path_);
}

}  // namespace deep_ois
