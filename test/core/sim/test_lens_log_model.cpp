// The simulator's realistic lens-shift log: read back through the camera's convention it is the
// true trajectory within its noise and quantisation, at its rate, late by its latency, with the
// configured share of lost samples and gaps; the same seed gives the same log.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "deep_ois/core/ois/lens_shift_log.h"
#include "deep_ois/core/sim/lens_log_model.h"

namespace deep_ois {
namespace sim {
namespace {

Eigen::Vector2d trajectory(double t) { return {3.0 * std::sin(2.0 * M_PI * 2.0 * t), -2.0 + t}; }

TEST(LensLogModel, ConventionLatencyNoiseAndDropouts) {
  LensLogConfig config;
  config.rate_hz = 200.0;
  config.latency_s = 0.03;
  config.noise_px = 0.02;
  config.quantisation = 1.0 / 32.0;
  config.dropout_probability = 0.05;
  config.convention.scale = 0.5;
  config.convention.swap_xy = true;
  config.convention.sign_y = -1.0;
  config.convention.time_offset_s = 0.01;
  const std::vector<LoggedLensSample> log = simulateLensLog(config, trajectory, 0.0, 10.0, 42);
  // 2001 instants, 5 % lost.
  EXPECT_NEAR(static_cast<double>(log.size()) / 2001.0, 0.95, 0.015);
  double worst_px = 0.0, sum_sq = 0.0;
  for (const LoggedLensSample& s : log) {
    const double t_camera = s.sample.stamp_s + config.convention.time_offset_s;
    EXPECT_NEAR(s.arrival_s, t_camera + config.latency_s, 1e-12);
    // On the quantisation grid (logged units).
    for (int k = 0; k < 2; ++k) {
      EXPECT_NEAR(s.sample.logged[k] / config.quantisation,
                  std::round(s.sample.logged[k] / config.quantisation), 1e-9);
    }
    ASSERT_TRUE(s.sample.covariance.has_value());
    const double error =
        (config.convention.toImagePx(s.sample.logged) - trajectory(t_camera)).norm();
    worst_px = std::max(worst_px, error);
    sum_sq += error * error;
  }
  // Noise 0.02 px per axis plus quantisation 1/32 logged unit = 1/64 px: RMS ~0.03 px.
  const double rms_px = std::sqrt(sum_sq / log.size());
  EXPECT_GT(rms_px, 0.015);
  EXPECT_LT(rms_px, 0.045);
  EXPECT_LT(worst_px, 0.2);

  // Read through a LensShiftLog with the same convention: the trajectory between samples.
  LensShiftLog reader(0.05, config.convention);
  for (const LoggedLensSample& s : log) ASSERT_TRUE(reader.add(s.sample).accepted());
  EXPECT_LT((reader.shiftAt(5.0012) - trajectory(5.0012)).norm(), 0.1);

  const std::vector<LoggedLensSample> again = simulateLensLog(config, trajectory, 0.0, 10.0, 42);
  ASSERT_EQ(again.size(), log.size());
  EXPECT_EQ(again.back().sample.logged, log.back().sample.logged);
}

TEST(LensLogModel, GapsAreLongerThanTheMaxGap) {
  LensLogConfig config;
  config.dropout_probability = 0.0;
  config.gap_rate_hz = 1.0;
  config.gap_duration_s = 0.1;
  const std::vector<LoggedLensSample> log = simulateLensLog(config, trajectory, 0.0, 20.0, 7);
  int gaps = 0;
  for (std::size_t k = 1; k < log.size(); ++k)
    gaps += log[k].sample.stamp_s - log[k - 1].sample.stamp_s > 0.05;
  EXPECT_GE(gaps, 8);  // ~20 expected (Poisson, 1 per second; overlapping ones merge)
  EXPECT_LE(gaps, 35);

  config.rate_hz = 0.0;
  EXPECT_NE(config.validate().find("rate_hz"), std::string::npos);
  EXPECT_THROW(simulateLensLog(config, trajectory, 0.0, 1.0, 7), std::invalid_argument);
}

}  // namespace
}  // namespace sim
}  // namespace deep_ois
