// Linear interpolation in samples taken on a uniform time grid (a lens trajectory at a fixed step).
#pragma once

#include <cstddef>

namespace deep_ois {

// `samples[j]` is the value at grid position j; `position` is a fractional grid position. Before
// the first sample the first is returned, after the last the last (the value is held). `Samples`
// is any non-empty indexable container (std::vector, std::deque) of Eigen vectors.
template <typename Samples>
auto interpolateOnUniformGrid(const Samples& samples, double position) ->
    typename Samples::value_type {
  const double last = static_cast<double>(samples.size() - 1);
  if (!(position > 0.0)) return samples.front();
  if (position >= last) return samples.back();
  const std::size_t j = static_cast<std::size_t>(position);
  const double alpha = position - static_cast<double>(j);
  return (1.0 - alpha) * samples[j] + alpha * samples[j + 1];
}

}  // namespace deep_ois
