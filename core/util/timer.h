#pragma once
#include <chrono>

namespace visloc {

// Wall-clock stopwatch on the monotonic clock, for per-step timings in statistics.
class Timer {
 public:
  Timer() : start_(std::chrono::steady_clock::now()) {}
  void Restart() { start_ = std::chrono::steady_clock::now(); }
  double ElapsedMs() const {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_)
        .count();
  }
  double ElapsedS() const { return ElapsedMs() * 1e-3; }

 private:
  std::chrono::steady_clock::time_point start_;
};

}  // namespace visloc
