// How a long offline job reports how far it is, without knowing who listens: a terminal progress
// bar in the command-line tools (tools/support/progress_bar.h), a throttled log line in a nodelet.
#pragma once

#include <cstddef>
#include <functional>

namespace deep_ois {

// Called with the items done so far and the total expected (0 when unknown).
using ProgressCallback = std::function<void(std::size_t done, std::size_t total)>;

}  // namespace deep_ois
