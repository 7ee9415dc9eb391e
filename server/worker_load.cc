#include "server/worker_load.h"

#include <sys/resource.h>

#include <algorithm>
#include <cmath>

namespace visloc::server {

WorkerLoad::WorkerLoad(int workers, std::chrono::seconds window, Clock::time_point start,
                       CpuSecondsFn process_cpu_s)
    : workers_(std::max(1, workers)),
      start_(start),
      process_cpu_s_(process_cpu_s),
      seconds_(static_cast<size_t>(std::max<int64_t>(kCpuSpanS + 1, window.count()))) {}

double WorkerLoad::ProcessCpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

double WorkerLoad::BucketUpperMs(int bucket) { return 0.1 * std::ldexp(1.0, bucket); }

int64_t WorkerLoad::SecondOf(Clock::time_point now) const {
  return std::max<int64_t>(0,
                           std::chrono::duration_cast<std::chrono::seconds>(now - start_).count());
}

WorkerLoad::Second& WorkerLoad::SlotFor(int64_t second, Clock::time_point now) {
  Second& slot = seconds_[static_cast<size_t>(second) % seconds_.size()];
  if (slot.second != second) {
    slot = Second();
    slot.second = second;
    slot.first_touch = now;
    slot.cpu_s_at_first_touch = process_cpu_s_();
  }
  return slot;
}

void WorkerLoad::AddWait(Clock::time_point now, Clock::duration waited) {
  const double ms = std::chrono::duration<double, std::milli>(waited).count();
  int bucket = 0;
  while (bucket < kWaitBuckets - 1 && ms >= BucketUpperMs(bucket)) ++bucket;
  const std::lock_guard<std::mutex> lock(mutex_);
  Second& slot = SlotFor(SecondOf(now), now);
  ++slot.frames;
  ++slot.waits[bucket];
}

void WorkerLoad::AddBusy(Clock::time_point now, Clock::duration held) {
  const std::lock_guard<std::mutex> lock(mutex_);
  SlotFor(SecondOf(now), now).busy_s += std::chrono::duration<double>(held).count();
}

WorkerLoadStats WorkerLoad::Over(Clock::time_point now) const {
  const int64_t last = SecondOf(now);
  const int64_t first = std::max<int64_t>(0, last - static_cast<int64_t>(seconds_.size()) + 1);
  WorkerLoadStats stats;
  // The current second counts for the part of it that has passed.
  stats.window_s = std::max(
      1e-3, std::chrono::duration<double>(now - start_).count() - static_cast<double>(first));
  std::array<int64_t, kWaitBuckets> waits{};
  double busy_s = 0.0;
  const Second* cpu_from = nullptr;  // The earliest slot of the CPU span.
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    for (const Second& s : seconds_) {
      if (s.second < first || s.second > last) continue;
      if (s.second >= last - kCpuSpanS && (!cpu_from || s.second < cpu_from->second)) {
        cpu_from = &s;
      }
      busy_s += s.busy_s;
      stats.frames += s.frames;
      for (int b = 0; b < kWaitBuckets; ++b) waits[b] += s.waits[b];
    }
    const double span_s =
        cpu_from ? std::chrono::duration<double>(now - cpu_from->first_touch).count() : 0.0;
    if (span_s >= 0.5) {
      stats.process_cpu_cores = (process_cpu_s_() - cpu_from->cpu_s_at_first_touch) / span_s;
    }
  }
  stats.busy_fraction = std::min(1.0, busy_s / (workers_ * stats.window_s));
  stats.frames_per_s = stats.frames / stats.window_s;
  const int64_t rank = static_cast<int64_t>(std::ceil(0.95 * stats.frames));
  int64_t seen = 0;
  for (int b = 0; b < kWaitBuckets && stats.frames > 0; ++b) {
    seen += waits[b];
    if (seen >= rank) {
      stats.wait_p95_ms = b == 0 ? 0.0 : BucketUpperMs(b);
      break;
    }
  }
  return stats;
}

}  // namespace visloc::server
