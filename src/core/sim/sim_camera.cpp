#include "deep_ois/core/sim/sim_camera.h"

#include <Eigen/Geometry>
#include <cmath>
#include <sstream>

namespace deep_ois {
namespace sim {

namespace {

constexpr double kPi = 3.14159265358979323846;
// Fixed-point iteration on the row of a rolling-shutter projection: stop below this change.
constexpr double kRowToleranceDeltaPx = 1e-6;
constexpr int kMaxRowIterations = 50;

// Whether the radial distortion is still one-to-one out to the normalised radius^2 `r2`:
// d(r * radial(r))/dr = 1 + 3 k1 r^2 + 5 k2 r^4 + 7 k3 r^6 stays positive on [0, r]. Beyond that
// radius a barrel lens model folds far off-axis points back into the image, which a real lens
// does not do.
bool radialDistortionMonotonic(const Eigen::Matrix<double, 5, 1>& d, double r2) {
  constexpr int kChecks = 16;
  for (int i = 1; i <= kChecks; ++i) {
    const double s = r2 * i / kChecks;
    if (!(1.0 + s * (3.0 * d[0] + s * (5.0 * d[1] + s * 7.0 * d[4])) > 0.0)) return false;
  }
  return true;
}

// The same for the equidistant (fisheye) model: theta_d = theta (1 + k1 theta^2 + k2 theta^4 +
// k3 theta^6 + k4 theta^8) must grow on [0, theta], theta the angle from the optical axis.
bool fisheyeDistortionMonotonic(const std::vector<double>& k, double theta) {
  constexpr int kChecks = 16;
  for (int i = 1; i <= kChecks; ++i) {
    const double s = theta * theta * i / kChecks;
    if (!(1.0 + s * (3.0 * k[0] + s * (5.0 * k[1] + s * (7.0 * k[2] + s * 9.0 * k[3]))) > 0.0)) return false;
  }
  return true;
}

}  // namespace

std::string SensorConfig::validate() const {
  std::ostringstream why;
  if (width_px < 2 || height_px < 2) {
    why << "width_px and height_px must be at least 2 (got " << width_px << "x" << height_px << ")";
  } else if (!(horizontal_fov_deg > 0.0 && horizontal_fov_deg < 170.0)) {
    why << "horizontal_fov_deg must be in (0, 170) degrees (got " << horizontal_fov_deg << ")";
  } else if (!(frame_rate_hz > 0.0 && frame_rate_hz <= 1000.0)) {
    why << "frame_rate_hz must be in (0, 1000] (got " << frame_rate_hz << ")";
  } else if (!(readout_time_s >= 0.0 && readout_time_s <= 1.0 / frame_rate_hz)) {
    why << "readout_time_s must be in [0, frame period " << 1.0 / frame_rate_hz << " s] (got "
        << readout_time_s << ")";
  } else if (!(exposure_time_s > 0.0 && exposure_time_s <= 1.0 / frame_rate_hz)) {
    why << "exposure_time_s must be in (0, frame period " << 1.0 / frame_rate_hz << " s] (got "
        << exposure_time_s << ")";
  } else if (distortion_model != "plumb_bob" && distortion_model != "equidistant") {
    why << "distortion_model must be plumb_bob or equidistant (got '" << distortion_model << "')";
  } else if (distortion_model == "plumb_bob" && distortion.size() > 5) {
    why << "distortion holds at most 5 plumb_bob coefficients k1, k2, p1, p2, k3 (got "
        << distortion.size() << ")";
  } else if (distortion_model == "equidistant" && distortion.size() > 4) {
    why << "distortion holds at most 4 equidistant coefficients k1, k2, k3, k4 (got "
        << distortion.size() << ")";
  } else if (supersampling < 1 || supersampling > 8) {
    why << "supersampling must be between 1 and 8 (got " << supersampling << ")";
  } else if (exposure_samples < 1 || exposure_samples > 64) {
    why << "exposure_samples must be between 1 and 64 (got " << exposure_samples << ")";
  } else if (!(brightness > 0.0 && std::isfinite(brightness))) {
    why << "brightness must be positive (got " << brightness << ")";
  } else if (!(full_well_electrons >= 1.0 && std::isfinite(full_well_electrons))) {
    why << "full_well_electrons must be at least 1 (got " << full_well_electrons << ")";
  } else if (!(read_noise_electrons >= 0.0 && std::isfinite(read_noise_electrons))) {
    why << "read_noise_electrons must be non-negative (got " << read_noise_electrons << ")";
  }
  if (!why.str().empty()) return why.str();
  for (double coefficient : distortion) {
    if (!std::isfinite(coefficient)) return "distortion coefficients must be finite";
  }
  return nominalCamera(*this).validate();
}

CameraModel nominalCamera(const SensorConfig& sensor) {
  const double f = 0.5 * sensor.width_px / std::tan(0.5 * sensor.horizontal_fov_deg * kPi / 180.0);
  Eigen::Matrix3d K;
  K << f, 0.0, 0.5 * (sensor.width_px - 1), 0.0, f, 0.5 * (sensor.height_px - 1), 0.0, 0.0, 1.0;
  const DistortionModel model =
      sensor.distortion_model == "equidistant" ? DistortionModel::kEquidistant : DistortionModel::kPlumbBob;
  return CameraModel(sensor.width_px, sensor.height_px, K, model, sensor.distortion);
}

SimCamera::SimCamera(const SensorConfig& sensor, const CameraMotion& motion, const OisModel& ois)
    : sensor_(sensor), motion_(motion), ois_(ois), nominal_(nominalCamera(sensor)) {}

double SimCamera::rowTime(double stamp_s, double row_px) const {
  return stamp_s + sensor_.readout_time_s * row_px / sensor_.height_px;
}

Eigen::Matrix3d SimCamera::intrinsicsAt(double t_s) const {
  Eigen::Matrix3d K = nominal_.K();
  const Eigen::Vector2d shift = ois_.lensShift(t_s);
  K(0, 2) += shift.x();
  K(1, 2) += shift.y();
  return K;
}

Eigen::Vector3d SimCamera::rayDirectionWorld(const Eigen::Vector2d& pixel, double t_s) const {
  // The lens carries its distortion with it: the distortion centre is the shifted principal point.
  const CameraModel lens(nominal_.width(), nominal_.height(), intrinsicsAt(t_s), nominal_.distortionModel(),
                         nominal_.coefficients());
  const Eigen::Vector3d ray_cam = lens.Kinv() * lens.undistort(pixel).homogeneous();
  return (motion_.pose(t_s).R_world_cam * ray_cam).normalized();
}

bool SimCamera::project(const Eigen::Vector3d& X_world_m, double t_s,
                        Eigen::Vector2d* pixel) const {
  const CameraPose pose = motion_.pose(t_s);
  const Eigen::Vector3d X_cam = pose.R_world_cam.transpose() * (X_world_m - pose.centre_world_m);
  if (!(X_cam.z() > 0.0)) return false;
  const double r2 = X_cam.head<2>().squaredNorm() / (X_cam.z() * X_cam.z());
  if (nominal_.hasDistortion() && nominal_.distortionModel() == DistortionModel::kPlumbBob &&
      !radialDistortionMonotonic(nominal_.distortion(), r2)) {
    return false;
  }
  if (nominal_.hasDistortion() && nominal_.distortionModel() == DistortionModel::kEquidistant &&
      !fisheyeDistortionMonotonic(nominal_.coefficients(), std::atan(std::sqrt(r2)))) {
    return false;
  }
  const CameraModel lens(nominal_.width(), nominal_.height(), intrinsicsAt(t_s), nominal_.distortionModel(),
                         nominal_.coefficients());
  *pixel = lens.distort((lens.K() * X_cam).hnormalized());
  return true;
}

bool SimCamera::projectRollingShutter(const Eigen::Vector3d& X_world_m, double stamp_s,
                                      Eigen::Vector2d* pixel, double* t_s) const {
  // row = y(X at the time of row): a contraction, since the image moves by far less than a row
  // during the readout of one row.
  double row = 0.5 * (sensor_.height_px - 1);
  Eigen::Vector2d p;
  bool settled = false;
  for (int iteration = 0; iteration < kMaxRowIterations; ++iteration) {
    if (!project(X_world_m, rowTime(stamp_s, row), &p)) return false;
    const double change = p.y() - row;
    row = p.y();
    if (std::abs(change) < kRowToleranceDeltaPx) {
      settled = true;
      break;
    }
  }
  if (!settled) return false;
  // Report the pixel at the time of the row it lies on (the last projection used the previous
  // row estimate, which differs by less than the tolerance).
  const double t = rowTime(stamp_s, row);
  if (!project(X_world_m, t, &p)) return false;
  if (!(p.x() >= -0.5 && p.x() < sensor_.width_px - 0.5 && p.y() >= -0.5 &&
        p.y() < sensor_.height_px - 0.5)) {
    return false;
  }
  *pixel = p;
  if (t_s != nullptr) *t_s = t;
  return true;
}

}  // namespace sim
}  // namespace deep_ois
