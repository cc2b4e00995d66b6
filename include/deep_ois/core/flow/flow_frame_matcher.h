// Pairs the gyro flows of a camera with the two frames each one spans, as both streams arrive.
//
// Why a class of its own: the compensation nodelet receives a gyro flow (frame a -> frame b) and
// the frames on separate topics, in any relative order, and either side can lose a message. The
// matcher decides for every flow, independently of the others, whether its frames are here (a
// pair to process), may still come (keep it), or can no longer come (drop it, with the reason).
// One flow whose frame never arrives costs only itself: no flow waits behind another.
//
// "Can no longer come": the frames of one topic arrive in stamp order, so a frame older than the
// newest frame received that is not in the cache was lost (or refused) upstream; a frame older
// than every cached frame while the cache is full left the cache (the flow came too late). A flow
// whose frames are newer than every frame received waits, at most `max_wait_s` of the caller's
// clock (wall time: the image stream may have stopped).
//
// Pure and single-threaded: stamps are integer nanoseconds, the clock is handed in by the caller,
// Flow and Frame are any copyable payloads (shared pointers in the nodelet). The caller locks.
#pragma once

#include <algorithm>
#include <utility>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <string>
#include <vector>

namespace deep_ois {

enum class FlowDropReason {
  kFrameNeverCame,   // a frame within the cached span that never arrived (or was refused)
  kFrameLeftCache,   // a frame older than every cached frame: the flow came too late
  kWaitedTooLong,    // no frame arrived for max_wait_s: the image stream stopped or lags
  kTooManyPending,   // more flows waiting than max_pending_flows: the oldest goes
  kTimeJumpedBack,   // the frames went back in time (a bag loop): flows of the old run go
};

inline const char* flowDropReasonText(FlowDropReason reason) {
  switch (reason) {
    case FlowDropReason::kFrameNeverCame: return "its frame never came";
    case FlowDropReason::kFrameLeftCache: return "its frame left the frame cache (the flow came too late)";
    case FlowDropReason::kWaitedTooLong: return "no frame came within max_wait";
    case FlowDropReason::kTooManyPending: return "too many flows waiting for frames";
    case FlowDropReason::kTimeJumpedBack: return "frame stamps went back in time (bag loop?)";
  }
  return "unknown";
}

struct FlowFrameMatcherOptions {
  std::size_t frame_cache_size = 30;   // frames kept (newest), >= 2
  std::size_t max_pending_flows = 60;  // flows waiting for frames, >= 1
  double max_wait_s = 1.0;             // caller's clock, seconds a flow may wait for a frame
};

template <typename Flow, typename Frame>
class FlowFrameMatcher {
 public:
  // One flow settled: matched (frames set) or dropped (reason set).
  struct Settled {
    Flow flow;
    std::int64_t stamp_a_ns = 0, stamp_b_ns = 0;
    bool matched = false;
    Frame frame_a{}, frame_b{};
    FlowDropReason reason = FlowDropReason::kFrameNeverCame;
  };

  explicit FlowFrameMatcher(FlowFrameMatcherOptions options) : options_(options) {
    options_.frame_cache_size = std::max<std::size_t>(options_.frame_cache_size, 2);
    options_.max_pending_flows = std::max<std::size_t>(options_.max_pending_flows, 1);
  }
  // A new wait bound (e.g. from dynamic_reconfigure), applied from the next expiry check on.
  void setMaxWait(double max_wait_s) { options_.max_wait_s = max_wait_s; }


  // A frame arrived. A frame with the stamp of the newest is ignored (duplicate); one older than
  // the newest restarts the cache (time went back) and drops the flows waiting for old-run frames.
  // Returns the flows settled by it, in stamp order.
  std::vector<Settled> addFrame(std::int64_t stamp_ns, const Frame& frame, double now_s) {
    std::vector<Settled> settled;
    if (!frames_.empty() && stamp_ns <= frames_.back().stamp_ns) {
      if (stamp_ns == frames_.back().stamp_ns) return settled;
      frames_.clear();
      for (const Pending& p : pending_) settled.push_back(drop(p, FlowDropReason::kTimeJumpedBack));
      pending_.clear();
    }
    frames_.push_back({stamp_ns, frame});
    while (frames_.size() > options_.frame_cache_size) frames_.pop_front();
    resolvePending(now_s, settled);
    return settled;
  }

  // A gyro flow from frame a to frame b arrived. Returns the flows settled by it (it, and the
  // oldest waiting one when too many wait), in stamp order.
  std::vector<Settled> addFlow(std::int64_t stamp_a_ns, std::int64_t stamp_b_ns, const Flow& flow, double now_s) {
    Pending p{flow, stamp_a_ns, stamp_b_ns, now_s};
    auto at = std::upper_bound(pending_.begin(), pending_.end(), stamp_b_ns,
                               [](std::int64_t s, const Pending& q) { return s < q.stamp_b_ns; });
    pending_.insert(at, p);
    std::vector<Settled> settled;
    if (pending_.size() > options_.max_pending_flows) {
      settled.push_back(drop(pending_.front(), FlowDropReason::kTooManyPending));
      pending_.pop_front();
    }
    resolvePending(now_s, settled);
    return settled;
  }

  // Settles the flows that waited longer than max_wait_s (call it from a timer, or any callback).
  std::vector<Settled> expire(double now_s) {
    std::vector<Settled> settled;
    resolvePending(now_s, settled);
    return settled;
  }

  void clear() {
    frames_.clear();
    pending_.clear();
  }
  std::size_t pendingFlows() const { return pending_.size(); }
  std::size_t cachedFrames() const { return frames_.size(); }

 private:
  struct CachedFrame {
    std::int64_t stamp_ns;
    Frame frame;
  };
  struct Pending {
    Flow flow;
    std::int64_t stamp_a_ns, stamp_b_ns;
    double received_s;
  };

  const CachedFrame* find(std::int64_t stamp_ns) const {
    for (auto it = frames_.rbegin(); it != frames_.rend(); ++it) {
      if (it->stamp_ns == stamp_ns) return &*it;
    }
    return nullptr;
  }

  static Settled drop(const Pending& p, FlowDropReason reason) {
    Settled s;
    s.flow = p.flow;
    s.stamp_a_ns = p.stamp_a_ns;
    s.stamp_b_ns = p.stamp_b_ns;
    s.reason = reason;
    return s;
  }

  // Why the frame with `stamp_ns` can no longer come, or false when it still may.
  bool lost(std::int64_t stamp_ns, FlowDropReason& reason) const {
    if (frames_.empty() || stamp_ns >= frames_.back().stamp_ns) return false;
    reason = frames_.size() == options_.frame_cache_size && stamp_ns < frames_.front().stamp_ns
                 ? FlowDropReason::kFrameLeftCache
                 : FlowDropReason::kFrameNeverCame;
    return true;
  }

  void resolvePending(double now_s, std::vector<Settled>& settled) {
    for (auto it = pending_.begin(); it != pending_.end();) {
      const CachedFrame* a = find(it->stamp_a_ns);
      const CachedFrame* b = find(it->stamp_b_ns);
      FlowDropReason reason;
      if (a != nullptr && b != nullptr) {
        Settled s;
        s.flow = it->flow;
        s.stamp_a_ns = it->stamp_a_ns;
        s.stamp_b_ns = it->stamp_b_ns;
        s.matched = true;
        s.frame_a = a->frame;
        s.frame_b = b->frame;
        settled.push_back(std::move(s));
      } else if ((a == nullptr && lost(it->stamp_a_ns, reason)) || (b == nullptr && lost(it->stamp_b_ns, reason))) {
        settled.push_back(drop(*it, reason));
      } else if (now_s - it->received_s > options_.max_wait_s) {
        settled.push_back(drop(*it, FlowDropReason::kWaitedTooLong));
      } else {
        ++it;
        continue;
      }
      it = pending_.erase(it);
    }
    std::stable_sort(settled.begin(), settled.end(),
                     [](const Settled& x, const Settled& y) { return x.stamp_b_ns < y.stamp_b_ns; });
  }

  FlowFrameMatcherOptions options_;
  std::deque<CachedFrame> frames_;  // ascending stamps, newest last
  std::deque<Pending> pending_;     // ascending stamp_b_ns
};

}  // namespace deep_ois
