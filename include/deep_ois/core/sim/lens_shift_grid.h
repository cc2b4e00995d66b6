// A lens-shift trajectory on a regular time grid: what the simulator's stabiliser (and its oracle)
// computes at its control rate, read at any time.
#pragma once

#include <Eigen/Core>
#include <vector>

namespace deep_ois {
namespace sim {

// A lens-shift trajectory (pixels) sampled at rate_hz from start_s: linear between samples, held
// outside them.
class LensShiftGrid {
 public:
  LensShiftGrid() = default;
  LensShiftGrid(double start_s, double rate_hz, std::vector<Eigen::Vector2d> samples);

  // Zero when empty.
  Eigen::Vector2d at(double t_s) const;
  bool empty() const { return samples_.empty(); }
  const std::vector<Eigen::Vector2d>& samples() const { return samples_; }

 private:
  double start_s_ = 0.0;
  double rate_hz_ = 1.0;
  std::vector<Eigen::Vector2d> samples_;
};

}  // namespace sim
}  // namespace deep_ois
