// The oracle of a stabiliser design: the simulator's own stabiliser for that design, a model of the
// package's stage library (core/sim/stabiliser_design_runner.h: moduleModel, designModel), so the
// package's own prediction with the design's exact stages, driven by a camera's gyro instead of the
// stabiliser's own. It is what the best possible model of
// that design could predict from the camera's IMU: the design's structure and parameters exact,
// only the gyro input differs (the camera IMU's noise, bias and rate instead of the stabiliser
// gyro's). A learned stabiliser model (core/ois/) that comes close to it has learned everything
// the camera's gyro can tell about the lens.
//
// Differences to the simulator's run, by design: no noise of the stabiliser's own sensors is drawn
// (its gyro's noise is replaced by the camera gyro's; the Hall sensor's noise is unknowable from
// any gyro, so its mean, zero). The simulator starts its stabiliser centred and at rest
// kSimulatorMarginS before the first frame, before the camera's IMU starts; the oracle starts at
// the time it is given (the simulator's start for its recordings) and holds the first gyro sample
// back to it, or at the first gyro sample.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <limits>
#include <vector>

#include "deep_ois/core/ois/stabiliser_model.h"
#include "deep_ois/core/sim/lens_shift_grid.h"
#include "deep_ois/core/sim/ois_model.h"
#include "deep_ois/core/sim/stabiliser_design.h"

namespace deep_ois {
namespace sim {

class StabiliserOracle {
 public:
  // `rates`: the camera's gyro in the camera's optical frame (CameraRateSample, e.g. cameraRates()
  // of core/ois/stabiliser_compensator.h), any clock, linear between samples. Samples not later
  // than the one before are dropped (counted). focal_px: the camera's focal length in pixels.
  // Throws std::invalid_argument for an invalid config (OisConfig::validate()), a config with
  // ois.enabled false or a lens_shift_csv (no stabiliser to run), a non-positive focal length or
  // fewer than two usable samples.
  // `start_s`: when the stabiliser starts, centred and at rest, on the gyro's clock; NaN: at the
  // first sample. Before the first sample the gyro is held at it.
  // A config with ois.design_seed set runs that generated design (as the simulator does).
  StabiliserOracle(const OisConfig& config, double focal_px,
                   const std::vector<CameraRateSample>& rates,
                   double start_s = std::numeric_limits<double>::quiet_NaN());
  // The oracle of a generated (or hand-built) stabiliser design (core/sim/stabiliser_design.h):
  // its chain at kDesignPhysicsRateHz on these rates, without its gyro's and Hall sensor's noise.
  // Throws std::invalid_argument for an invalid design, as above for the rest.
  StabiliserOracle(const StabiliserDesign& design, double focal_px,
                   const std::vector<CameraRateSample>& rates,
                   double start_s = std::numeric_limits<double>::quiet_NaN());

  // Within [start, last sample].
  bool covers(double t_s) const { return t_s >= start_s_ && t_s <= last_s_; }
  // The lens shift (pixels, x right, y down) at t_s on the gyro's clock.
  Eigen::Vector2d lensShift(double t_s) const { return grid_.at(t_s); }
  int droppedSamples() const { return dropped_; }

 private:
  // Runs `run(start_s, steps, rate)` at rate_hz over the usable samples from start_s.
  using Runner = std::function<LensShiftGrid(
      double start_s, int steps, const std::function<Eigen::Vector3d(double t_s)>& rate)>;
  void runOver(const std::vector<CameraRateSample>& rates, double start_s, double rate_hz,
               const Runner& run);

  double start_s_ = 0.0, last_s_ = 0.0;
  int dropped_ = 0;
  LensShiftGrid grid_;
};

}  // namespace sim
}  // namespace deep_ois
