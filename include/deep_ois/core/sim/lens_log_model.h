// What a real camera's lens-shift log looks like, made from the simulator's true lens trajectory:
// its own sample rate, delivery latency, sensor noise, quantisation, lost samples and gaps, and
// the camera's own scale/sign/axis convention and clock. The published stream is what a phone
// gives (Android camera2 OisSample: ~200 Hz on current phones, delivered with the capture result a
// frame or more after the fact); the truth stays on /ground_truth/lens_shift.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "deep_ois/core/ois/lens_shift_log.h"

namespace deep_ois {
namespace sim {

struct LensLogConfig {
  bool enabled = true;     // publish a log (only for OIS cameras: a non-OIS twin has none)
  double rate_hz = 200.0;  // samples per second (camera2 OisSample rate of recent phones)
  // Delivery delay: a sample is recorded this long after the instant it describes (camera2
  // delivers a frame's samples with its capture result). Seconds.
  double latency_s = 0.033;
  double noise_px = 0.02;             // white noise per sample and axis, published-image pixels
  double quantisation = 1.0 / 32.0;   // step of the logged numbers, logged units (0 = none)
  double dropout_probability = 0.01;  // each sample is lost with this probability
  // Longer outages (a paused stream, a full queue): Poisson rate per second and length, seconds.
  double gap_rate_hz = 0.0;
  double gap_duration_s = 0.1;
  // The camera's convention: logged = convention^-1 (image shift), logged stamp = camera time -
  // convention.time_offset_s (LensShiftLogConvention says the mapping from log to image).
  LensShiftLogConvention convention;

  std::string validate() const;  // empty, or a sentence naming the bad field
};

struct LoggedLensSample {
  LensShiftLogSample sample;  // as logged: the log's clock and units, with its noise covariance
  double arrival_s = 0.0;     // camera-clock time the sample is delivered (recorded), seconds
};

// The log over [t0_s, t1_s] (camera clock) of the lens trajectory `true_shift_px` (camera clock ->
// published-image pixels). Same seed, same log; arrivals are non-decreasing in sample order.
// Throws std::invalid_argument with the validate() sentence.
std::vector<LoggedLensSample> simulateLensLog(
    const LensLogConfig& config, const std::function<Eigen::Vector2d(double)>& true_shift_px,
    double t0_s, double t1_s, std::uint32_t seed);

}  // namespace sim
}  // namespace deep_ois
