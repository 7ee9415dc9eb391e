#pragma once
// Per-session frame-rate limit (product.md: limits with clear errors): a token bucket that
// admits `rate_hz` frames per second on average with bursts of up to one second's worth, so a
// client that briefly catches up after a network hiccup is not punished, while one that sends
// far faster than its camera can run takes no more than its share of the server's cores.

#include <algorithm>
#include <chrono>

namespace visloc::server {

class FrameRateLimiter {
 public:
  using Clock = std::chrono::steady_clock;

  // rate_hz <= 0: no limit.
  explicit FrameRateLimiter(double rate_hz)
      : rate_hz_(rate_hz), capacity_(std::max(1.0, rate_hz)), tokens_(capacity_) {}

  // True when a frame arriving at `now` is admitted (consumes one token).
  bool Admit(Clock::time_point now) {
    if (rate_hz_ <= 0) return true;
    if (started_) {
      const double elapsed_s = std::chrono::duration<double>(now - last_).count();
      tokens_ = std::min(capacity_, tokens_ + std::max(0.0, elapsed_s) * rate_hz_);
    }
    started_ = true;
    last_ = now;
    if (tokens_ < 1.0) return false;
    tokens_ -= 1.0;
    return true;
  }

  double rate_hz() const { return rate_hz_; }

 private:
  double rate_hz_;
  double capacity_;  // Tokens: one second of frames, at least one.
  double tokens_;
  bool started_ = false;
  Clock::time_point last_;
};

}  // namespace visloc::server
