#pragma once
#include <time.h>

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

// The calling thread's CPU time: a step's own work, without the time other threads held its
// core (a wall-clock Timer on a busy machine counts both).
class ThreadCpuTimer {
 public:
  ThreadCpuTimer() : start_s_(Now()) {}
  double ElapsedS() const { return Now() - start_s_; }

 private:
  static double Now() {
    timespec t{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
  }
  double start_s_;
};

}  // namespace visloc
