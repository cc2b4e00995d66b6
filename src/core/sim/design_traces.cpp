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

  // Streams of the motion seed, as the simulator's (motion 1, IMU 4), and the stabiliser's own
  // noise from both seeds. The stabiliser starts centred and at rest at t = 0, with the gyro, so
  // that designLensShifts on the trace's gyro is the design's oracle from the same start.
  const CameraMotion motion(options.motion, streamSeed(motion_seed, 1), 0.0, options.duration_s);
  const int steps = static_cast<int>(std::ceil(options.duration_s * kDesignPhysicsRateHz));
  std::mt19937 noise(streamSeed(motion_seed ^ design_seed, 2));
  const LensShiftGrid lens = runDesign(design, options.focal_px, 0.0, steps,
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
