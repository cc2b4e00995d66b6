// The online calibration's clock model (offset + drift rate, the windows' 1-sigma learned from the
// innovations) on synthetic window measurements: a known drift recovered, a jump told apart, and
// the reported 1-sigma covering the truth as a 1-sigma should when the windows understate their
// own error and share it with their neighbours, as overlapping windows on one stretch of motion do.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <iostream>
#include <random>

#include "deep_ois/core/online/clock_offset_filter.h"

namespace deep_ois {
namespace {

// Windows of 3 s every 1.5 s (overlap 2), each reporting `reported_sigma_s` while its actual error
// is `actual_sigma_s`, correlated from one window to the next by `correlation` (an AR(1) process:
// the neighbours share half their pairs and the same stretch of motion).
struct SyntheticWindows {
  double reported_sigma_s = 0.2e-3;
  double actual_sigma_s = 0.2e-3;
  double correlation = 0.0;
  double interval_s = 1.5;
  std::uint32_t seed = 1;
};

struct Coverage {
  int windows = 0, within_1 = 0, within_2 = 0;
  double share1() const { return static_cast<double>(within_1) / windows; }
  double share2() const { return static_cast<double>(within_2) / windows; }
};

// Runs `truth` (offset at camera time t) through the filter for duration_s; coverage counted after
// `from_s` on the offset at each window's end (where the estimator reports it), against
// `scored_truth` when the windows see another offset than the true one.
Coverage run(ClockOffsetFilter& filter, const SyntheticWindows& windows, const std::function<double(double)>& truth,
             double duration_s, double from_s, std::function<double(double)> scored_truth = nullptr) {
  if (!scored_truth) scored_truth = truth;
  std::mt19937 random(windows.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  Coverage coverage;
  double error_s = windows.actual_sigma_s * normal(random);
  const double innovation_share = std::sqrt(1.0 - windows.correlation * windows.correlation);
  for (double end_s = 3.0; end_s <= duration_s; end_s += windows.interval_s) {
    const double middle_s = end_s - 1.5;
    error_s = windows.correlation * error_s + innovation_share * windows.actual_sigma_s * normal(random);
    const ClockOffsetFilter::Outcome outcome =
        filter.add({middle_s, truth(middle_s) + error_s, windows.reported_sigma_s, 3.0 / windows.interval_s});
    if (outcome == ClockOffsetFilter::Outcome::kJump) {
      filter.restart({middle_s, truth(middle_s) + error_s, windows.reported_sigma_s, 1.0});
    }
    if (end_s < from_s) continue;
    const double miss_s = std::abs(filter.offsetAt(end_s) - scored_truth(end_s));
    const double sigma_s = filter.sigmaAt(end_s);
    ++coverage.windows;
    if (miss_s <= sigma_s) ++coverage.within_1;
    if (miss_s <= 2.0 * sigma_s) ++coverage.within_2;
  }
  return coverage;
}

TEST(ClockOffsetFilter, RecoversAKnownDrift) {
  ClockOffsetFilter filter;
  SyntheticWindows windows;
  windows.correlation = 0.5;
  const auto truth = [](double t) { return 0.023 + 3e-3 * t / 60.0; };  // 3 ms a minute
  run(filter, windows, truth, 60.0, 0.0);
  std::cout << "[ measured ] after 60 s: offset error " << (filter.offsetAt(58.5) - truth(58.5)) * 1e3
            << " ms (1-sigma " << filter.sigmaAt(58.5) * 1e3 << " ms), rate " << filter.rate() * 6e4
            << " ms/min (true 3)\n";
  EXPECT_NEAR(filter.offsetAt(58.5), truth(58.5), 0.2e-3);
  EXPECT_NEAR(filter.rate(), 5e-5, 2e-5);
}

// The drift rate applied with the calibration (OnlineCalibrationOptions::applied_rate_sigmas, 1):
// windows missing alike for many windows in a row (lag-1 correlation 0.9, as one stretch of motion
// gives) make a steady clock's line lean; its 1-sigma with the shared error's floor
// (systematic_rate_sigma) rarely calls that a drift, while 3 ms a minute is told from zero.
TEST(ClockOffsetFilter, TellsADriftRateFromTheWindowsSharedError) {
  int steady_told = 0, drift_told = 0;
  constexpr int kRecordings = 20;
  for (std::uint32_t seed = 1; seed <= kRecordings; ++seed) {
    SyntheticWindows windows;
    windows.correlation = 0.9;
    windows.seed = seed;
    ClockOffsetFilter steady, drifting;
    run(steady, windows, [](double) { return 0.023; }, 60.0, 0.0);
    run(drifting, windows, [](double t) { return 0.023 + 3e-3 * t / 60.0; }, 40.0, 0.0);
    if (std::abs(steady.rate()) > 1.0 * steady.rateSigma()) ++steady_told;
    if (std::abs(drifting.rate()) > 1.0 * drifting.rateSigma()) ++drift_told;
    EXPECT_GE(steady.rateSigma(), steady.options().systematic_rate_sigma);
  }
  std::cout << "[ measured ] a drift rate told from zero: steady clock " << steady_told << " of " << kRecordings
            << " (60 s), 3 ms a minute " << drift_told << " of " << kRecordings << " (40 s)\n";
  EXPECT_LE(steady_told, 3);   // 2 measured
  EXPECT_GE(drift_told, 18);   // 20 measured
}

TEST(ClockOffsetFilter, TellsAJumpFromTheWindowsNoise) {
  ClockOffsetFilter filter;
  SyntheticWindows windows;
  windows.correlation = 0.5;
  windows.actual_sigma_s = 0.4e-3;  // twice what the windows report, as on the simulator
  int jumps = 0;
  std::mt19937 random(3);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (double end_s = 3.0; end_s <= 60.0; end_s += 1.5) {
    const double middle_s = end_s - 1.5;
    // A 10 ms jump at 30 s: the first window past it is the first to show it.
    const double truth_s = 0.023 + (middle_s >= 30.0 ? 0.010 : 0.0);
    const ClockMeasurement measured{middle_s, truth_s + windows.actual_sigma_s * normal(random),
                                    windows.reported_sigma_s, 2.0};
    if (filter.add(measured) == ClockOffsetFilter::Outcome::kJump) {
      ++jumps;
      EXPECT_GE(middle_s, 30.0);
      filter.restart(measured);
    }
  }
  EXPECT_EQ(jumps, 1);
  EXPECT_NEAR(filter.offsetAt(58.5), 0.033, 0.5e-3);
}

// Coverage of the reported 1-sigma over 20 recordings of 60 s (after the first 10 s), windows of
// 3 s every 1.5 s on an offset drifting 3 ms a minute, against the same filter that takes the
// windows' 1-sigma as reported. What is tested is the learning of the windows' scale: a filter
// that forgets within ~10 s (walks of 3e-5 s/sqrt(s) and 1.5e-5 /sqrt(s)), on windows that share
// no error over the recording (no floor). With the default walks (a line over many windows) the
// same AR(1) windows are covered less (47 % / 79 % when they report half their error): AR(1) is
// not what the simulator's windows are (their shared error lasts the recording; the floor's test
// below); benchmark_online_calibration measures the default model's coverage on them.
ClockModelOptions forgettingWithinTenSeconds() {
  ClockModelOptions options;
  options.offset_random_walk_s_per_sqrt_s = 3e-5;
  options.rate_random_walk_per_sqrt_s = 1.5e-5;
  options.systematic_sigma_s = 0.0;
  return options;
}
struct Compared {
  Coverage learned, trusting;
  double scale = 0.0;  // mean learned scale
};
Compared compare(SyntheticWindows windows) {
  const auto truth = [](double t) { return 0.023 + 3e-3 * t / 60.0; };
  Compared out;
  for (std::uint32_t seed = 1; seed <= 20; ++seed) {
    windows.seed = seed;
    ClockOffsetFilter filter(forgettingWithinTenSeconds());
    const Coverage one = run(filter, windows, truth, 60.0, 10.0);
    out.learned.windows += one.windows;
    out.learned.within_1 += one.within_1;
    out.learned.within_2 += one.within_2;
    out.scale += filter.noiseScale() / 20.0;
    ClockModelOptions trusting = forgettingWithinTenSeconds();
    trusting.min_noise_scale = trusting.max_noise_scale = 1.0;  // the windows' 1-sigma taken as it is
    ClockOffsetFilter naive(trusting);
    const Coverage other = run(naive, windows, truth, 60.0, 10.0);
    out.trusting.windows += other.windows;
    out.trusting.within_1 += other.within_1;
    out.trusting.within_2 += other.within_2;
  }
  std::cout << "[ measured ] windows reporting " << windows.reported_sigma_s * 1e3 << " ms, missing by "
            << windows.actual_sigma_s * 1e3 << " ms (correlation " << windows.correlation << "), "
            << out.learned.windows << " windows: learned scale " << out.scale << ": " << 100 * out.learned.share1()
            << " % within 1 sigma, " << 100 * out.learned.share2() << " % within 2 sigma; as reported "
            << 100 * out.trusting.share1() << " % / " << 100 * out.trusting.share2() << " %\n";
  return out;
}

// A 1-sigma covers 68 % and a 2-sigma 95 % of a Gaussian error; the bounds leave room for the
// learning's own noise over 20 short recordings.
TEST(ClockOffsetFilter, ItsOneSigmaCoversTheTruthWhenTheWindowsUnderstateTheirError) {
  SyntheticWindows windows;
  windows.actual_sigma_s = 0.4e-3;  // twice what they report
  windows.correlation = 0.3;
  const Compared result = compare(windows);
  EXPECT_GT(result.scale, 1.3);
  EXPECT_GE(result.learned.share1(), 0.55);
  EXPECT_GE(result.learned.share2(), 0.85);
  EXPECT_LT(result.trusting.share2(), result.learned.share2() - 0.1);
}

TEST(ClockOffsetFilter, ItsOneSigmaNarrowsWhenTheWindowsOverstateTheirError) {
  SyntheticWindows windows;
  windows.actual_sigma_s = 0.1e-3;  // half what they report
  windows.correlation = 0.3;
  const Compared result = compare(windows);
  EXPECT_LT(result.scale, 0.8);
  EXPECT_GE(result.learned.share1(), 0.55);
  EXPECT_GE(result.learned.share2(), 0.85);
  EXPECT_LE(result.learned.share1(), 0.9);  // not honest by being uselessly wide
  EXPECT_GT(result.trusting.share1(), result.learned.share1());
}

TEST(ClockOffsetFilter, HonestWindowsKeepTheirOneSigma) {
  SyntheticWindows windows;  // independent errors of the size they report
  const Compared result = compare(windows);
  EXPECT_GT(result.scale, 0.6);
  EXPECT_LT(result.scale, 1.5);
  EXPECT_GE(result.learned.share1(), 0.6);
  EXPECT_GE(result.learned.share2(), 0.9);
}

// Windows that share an error over the whole recording (drawn once per recording, 0.12 ms), as
// the simulator's do: the filter takes it for the offset, so only the floor keeps the 1-sigma honest.
TEST(ClockOffsetFilter, ItsFloorCoversAnErrorTheWindowsShareOverTheRecording) {
  const auto truth = [](double t) { return 0.023 + 3e-3 * t / 60.0; };
  Coverage with_floor, without;
  std::mt19937 random(7);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (std::uint32_t seed = 1; seed <= 20; ++seed) {
    const double shared_s = 0.12e-3 * normal(random);
    const auto biased = [&](double t) { return truth(t) + shared_s; };  // what the windows see
    SyntheticWindows windows;
    windows.reported_sigma_s = windows.actual_sigma_s = 0.2e-3;
    windows.correlation = 0.3;
    windows.seed = seed;
    for (const bool floor : {true, false}) {
      ClockModelOptions options;
      if (!floor) options.systematic_sigma_s = 0.0;
      ClockOffsetFilter filter(options);
      const Coverage one = run(filter, windows, biased, 60.0, 10.0, truth);
      Coverage& total = floor ? with_floor : without;
      total.windows += one.windows;
      total.within_1 += one.within_1;
      total.within_2 += one.within_2;
    }
  }
  std::cout << "[ measured ] windows sharing 0.12 ms over each recording: " << 100 * with_floor.share1() << " % / "
            << 100 * with_floor.share2() << " % within 1 / 2 sigma with the floor, " << 100 * without.share1()
            << " % / " << 100 * without.share2() << " % without\n";
  EXPECT_GE(with_floor.share1(), 0.55);
  EXPECT_GE(with_floor.share2(), 0.85);
  EXPECT_LT(without.share2(), with_floor.share2() - 0.1);
}

TEST(ClockOffsetFilter, BadInputIsNamed) {
  ClockModelOptions options;
  options.jump_sigmas = 0.5;
  EXPECT_NE(options.validate().find("jump_sigmas"), std::string::npos);
  EXPECT_THROW(ClockOffsetFilter{options}, std::invalid_argument);
  ClockOffsetFilter filter;
  EXPECT_THROW(filter.add({0.0, NAN, 1e-3, 1.0}), std::invalid_argument);
  EXPECT_THROW(filter.add({0.0, 0.02, 0.0, 1.0}), std::invalid_argument);
}

}  // namespace
}  // namespace deep_ois
