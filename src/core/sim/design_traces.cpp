#include "deep_ois/core/sim/design_traces.h"

#include <cmath>
#include <random>
#include <sstream>
#include <stdexcept>

#include "deep_ois/core/common/portable_random.h"
#include "deep_ois/core/sim/stabiliser_design_runner.h"
#include "deep_ois/core/sim/stabiliser_oracle.h"

namespace deep_ois {
namespace sim {

namespace {

// The simulator's margin (kSimulatorMarginS in simulator.h, not included: that header pulls in the
// renderer): the stabiliser settles from rest before t = 0.
constexpr double kMarginS = 0.25;

}  // namespace

std::vector<Eigen::Vector2d> designLensShifts(const StabiliserDesign& design, double focal_px,
                                              const std::vector<CameraRateSample>& gyro,
                                              double start_s) {
  const StabiliserOracle oracle(design, focal_px, gyro, start_s);
  std::vector<Eigen::Vector2d> lens;
  lens.reserve(gyro.size());
  for (const CameraRateSample& sample : gyro) lens.push_back(oracle.lensShift(sample.stamp_s));
  return lens;
}

std::string DesignTraceOptions::validate() const {
  std::ostringstream why;
  if (!(duration_s > 0.0) || duration_s > 3600.0) {
    why << "duration_s: must be in (0, 3600] s (got " << duration_s << ")";
  } else if (!(focal_px > 0.0) || !std::isfinite(focal_px)) {
    why << "focal_px: must be positive (got " << focal_px << ")";
  } else if (const std::string m = motion.validate(); !m.empty()) {
    why << "motion: " << m;
  } else if (const std::string i = imu.validate(); !i.empty()) {
    why << "imu: " << i;
  } else if (imu.time_offset_s != 0.0) {
    why << "imu.time_offset_s: must be 0 (the trace has one clock; got " << imu.time_offset_s << ")";
  }
  return why.str();
}

DesignTrace simulateDesignTrace(std::uint32_t design_seed, std::uint32_t motion_seed,
                                const DesignTraceOptions& options) {
  const std::string problem = options.validate();
  if (!problem.empty()) throw std::invalid_argument("design trace: " + problem);
  const StabiliserDesign design = generateDesign(design_seed);
  DesignTrace trace;
  trace.design_seed = design_seed;
  trace.motion_seed = motion_seed;
  trace.design_class = designClass(design);
  trace.split = designSplit(design_seed);

  // Streams of the motion seed, as the simulator's (motion 1, stabiliser noise 2, IMU 4), mixed
  // with the design seed for the stabiliser's own noise.
  const CameraMotion motion(options.motion, streamSeed(motion_seed, 1), -kMarginS,
                            options.duration_s + kMarginS);
  const int steps = static_cast<int>(std::ceil((motion.endTime() - motion.startTime()) * kDesignPhysicsRateHz));
  std::mt19937 noise(streamSeed(motion_seed ^ design_seed, 2));
  const LensShiftGrid lens = runDesign(design, options.focal_px, motion.startTime(), steps,
                                       [&motion](double t_s) { return motion.angularVelocity(t_s); },
                                       &noise);
  for (const ImuMeasurement& m :
       sampleImu(options.imu, motion, streamSeed(motion_seed, 4), 0.0, options.duration_s)) {
    trace.gyro.push_back({m.stamp_s, options.imu.imu_to_camera_rotation * m.angular_velocity_rad_s});
    trace.lens_px.push_back(lens.at(m.stamp_s));
  }
  return trace;
}

}  // namespace sim
}  // namespace deep_ois
