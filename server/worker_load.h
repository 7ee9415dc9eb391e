#pragma once
// How loaded the engine's workers are, over a sliding window: the share of their time spent on
// frames, and how long frames waited for a free worker. Admission control (admission.h), the
// /metrics page and the operator's page read it. Times are the server's steady clock; every
// method takes `now` so tests drive the clock.

#include <array>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <vector>

namespace visloc::server {

struct WorkerLoadStats {
  double window_s = 0.0;       // The time the figures cover (the window, less at start-up).
  double busy_fraction = 0.0;  // Worker-seconds on frames over workers x window_s, 0..1.
  double frames_per_s = 0.0;   // Frames that took a worker.
  double wait_p95_ms = 0.0;    // A frame's wait for a free worker, 95th percentile (bucketed).
  int64_t frames = 0;
  // The cores the whole process used over the last few seconds (the engine, the link's threads
  // receiving and parsing frames, mapping jobs); 0 before there is a span to measure.
  double process_cpu_cores = 0.0;
};

class WorkerLoad {
 public:
  using Clock = std::chrono::steady_clock;
  // The process's CPU time so far (s): getrusage in production, a table in tests.
  using CpuSecondsFn = double (*)();
  WorkerLoad(int workers, std::chrono::seconds window, Clock::time_point start = Clock::now(),
             CpuSecondsFn process_cpu_s = &ProcessCpuSeconds);
  static double ProcessCpuSeconds();

  // A frame took a worker after waiting `waited`.
  void AddWait(Clock::time_point now, Clock::duration waited);
  // Workers were held on frames for `held` in all (a frame's one, and a rig's spare ones).
  void AddBusy(Clock::time_point now, Clock::duration held);
  // The last window up to `now`.
  WorkerLoadStats Over(Clock::time_point now) const;

 private:
  // Waits in buckets: below 0.1 ms, then doubling edges from 0.1 ms up to 6.5 s.
  static constexpr int kWaitBuckets = 18;
  struct Second {
    int64_t second = -1;            // Since start; -1: never used.
    Clock::time_point first_touch;  // When the slot was opened, and the process's CPU time then.
    double cpu_s_at_first_touch = 0.0;
    double busy_s = 0.0;
    int64_t frames = 0;
    std::array<int64_t, kWaitBuckets> waits{};
  };
  static double BucketUpperMs(int bucket);
  int64_t SecondOf(Clock::time_point now) const;
  Second& SlotFor(int64_t second, Clock::time_point now);
  // How far back the process's CPU use is measured.
  static constexpr int kCpuSpanS = 3;

  const int workers_;
  const Clock::time_point start_;
  const CpuSecondsFn process_cpu_s_;
  mutable std::mutex mutex_;
  std::vector<Second> seconds_;  // A ring, one slot per second of the window.
};

}  // namespace visloc::server
