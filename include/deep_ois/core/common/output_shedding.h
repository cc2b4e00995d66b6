// Graceful overload: which optional outputs a pipeline that falls behind leaves out, and in what
// order, before it drops a pair.
//
// Why: a pipeline starved of CPU (other processes on the robot's cores) that drops whole pairs
// once it is late leaves a robot without any aligned frame; the outputs a pair can go without
// (the compensation's ghost overlay, warped frame and colour image, for a person watching) cost
// more than the compensated flow itself. So when a pair is late, the costliest optional output
// (by the measured wall time per pair) is left out first, then the next, until the pipeline keeps
// up; only when even the plain output is late does the caller drop the pair (its own rule, e.g.
// the compensation's ~max_lag). When the lag stays low for a while, the outputs come back one at a
// time, the cheapest first.
//
// Not thread-safe: one caller (the compensation's callbacks, under its mutex). Pure C++: no ROS.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace deep_ois {

struct OutputSheddingOptions {
  // A pair later than this (seconds beyond the pipeline's smallest delay) sheds one more output.
  double shed_above_s = 0.125;
  // restore_after_pairs consecutive pairs later than this at most give one output back.
  double restore_below_s = 0.05;
  int restore_after_pairs = 30;
  // Weight of the newest measurement in each output's running mean cost.
  double cost_smoothing = 0.1;

  // Empty when usable; otherwise a sentence naming the bad field.
  std::string validate() const;
};

class OutputShedding {
 public:
  // `outputs`: the optional outputs' names (e.g. "aligned/ghost"). Throws std::invalid_argument
  // with validate()'s sentence, or for no output.
  OutputShedding(std::vector<std::string> outputs, const OutputSheddingOptions& options = {});

  // One pair about to be processed `lag_s` late: sheds one more output, gives one back after a
  // calm stretch, or keeps the level. Returns the number of outputs shed for this pair.
  std::size_t beforePair(double lag_s);
  // Whether output `index` is left out of the current pair. Counts it as shed when `wanted` (it
  // has a subscriber; an output nobody wants is never computed anyway).
  bool shed(std::size_t index, bool wanted = true);
  // The wall time output `index` took for one pair (seconds), into its running mean.
  void measured(std::size_t index, double seconds);

  std::size_t level() const { return level_; }
  std::size_t outputCount() const { return outputs_.size(); }
  const std::string& name(std::size_t index) const { return outputs_[index]; }
  double meanCostS(std::size_t index) const { return cost_s_[index]; }
  bool everMeasured(std::size_t index) const { return measured_[index]; }
  // The order outputs are shed in (indices): fixed when shedding starts (the costliest measured
  // first, unmeasured last), recomputed whenever everything is back, so it never reorders while
  // something is shed.
  const std::vector<std::size_t>& order() const { return order_; }
  // Pairs output `index` was shed from (wanted), pairs seen, and how often the level went up.
  std::size_t shedCount(std::size_t index) const { return shed_counts_[index]; }
  std::size_t pairs() const { return pairs_; }
  std::size_t escalations() const { return escalations_; }
  // "aligned/ghost 2.10 ms, aligned/image_raw 1.30 ms, ..." in shedding order.
  std::string describeOrder() const;
  // "nothing", or the names shed now.
  std::string describeShed() const;
  // "aligned/ghost 120, aligned/image_raw 80, ... of 900 pairs".
  std::string describeCounts() const;

 private:
  void sortByCost();

  std::vector<std::string> outputs_;
  OutputSheddingOptions options_;
  std::vector<double> cost_s_;
  std::vector<bool> measured_;
  std::vector<std::size_t> order_;
  std::vector<std::size_t> shed_counts_;
  std::size_t level_ = 0;
  int calm_pairs_ = 0;
  std::size_t pairs_ = 0;
  std::size_t escalations_ = 0;
};

}  // namespace deep_ois
