#pragma once
// A counting semaphore: the worker pool's size as permits. Sessions wait here for their turn to
// run the engine, so N sessions share the machine's cores instead of oversubscribing them. The
// scoped holders (WorkPermit, SparePermits) account their waits and work in the pool's load.

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <mutex>

#include "server/worker_load.h"

namespace visloc::server {

class WorkPermits {
 public:
  // `load_window`: how far back load() looks.
  explicit WorkPermits(int permits, std::chrono::seconds load_window = std::chrono::seconds(10))
      : permits_(permits), free_(permits), load_(permits, load_window) {}
  void Acquire() {
    std::unique_lock<std::mutex> lock(mutex_);
    available_.wait(lock, [this] { return free_ > 0; });
    --free_;
    peak_in_use_ = std::max(peak_in_use_, permits_ - free_);
  }
  void Release() {
    std::lock_guard<std::mutex> lock(mutex_);
    ++free_;
    available_.notify_one();
  }
  // Takes up to `wanted` permits that are free now, without waiting; how many it took.
  int TryAcquire(int wanted) {
    std::lock_guard<std::mutex> lock(mutex_);
    const int taken = std::max(0, std::min(wanted, free_));
    free_ -= taken;
    peak_in_use_ = std::max(peak_in_use_, permits_ - free_);
    return taken;
  }
  int permits() const { return permits_; }
  int in_use() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return permits_ - free_;
  }
  // Waits and work of the scoped holders, over the last window.
  WorkerLoad& load() { return load_; }
  const WorkerLoad& load() const { return load_; }
  // The most permits ever held at once (for tests, the session-end log and the status).
  int peak_in_use() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return peak_in_use_;
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable available_;
  const int permits_;
  int free_;
  int peak_in_use_ = 0;
  WorkerLoad load_;
};

// Holds one permit for its scope; its wait and its work count in the pool's load.
class WorkPermit {
 public:
  explicit WorkPermit(WorkPermits* permits) : permits_(permits) {
    const auto asked = WorkerLoad::Clock::now();
    permits_->Acquire();
    acquired_ = WorkerLoad::Clock::now();
    permits_->load().AddWait(acquired_, acquired_ - asked);
  }
  ~WorkPermit() {
    permits_->Release();
    const auto now = WorkerLoad::Clock::now();
    permits_->load().AddBusy(now, now - acquired_);
  }
  WorkPermit(const WorkPermit&) = delete;
  WorkPermit& operator=(const WorkPermit&) = delete;

 private:
  WorkPermits* permits_;
  WorkerLoad::Clock::time_point acquired_;
};

// Holds, for its scope, up to `wanted` further permits that are free when it starts: the idle
// cores a rig session's frame may use for its cameras side by side, never waited for (a busy
// server runs the frame's cameras one after the other on its one permit).
class SparePermits {
 public:
  SparePermits(WorkPermits* permits, int wanted)
      : permits_(permits),
        taken_(wanted > 0 ? permits->TryAcquire(wanted) : 0),
        acquired_(WorkerLoad::Clock::now()) {}
  ~SparePermits() {
    for (int i = 0; i < taken_; ++i) permits_->Release();
    // Counted as busy for their whole scope: a rig's frame keeps them until its cameras are done.
    const auto now = WorkerLoad::Clock::now();
    if (taken_ > 0) permits_->load().AddBusy(now, taken_ * (now - acquired_));
  }
  SparePermits(const SparePermits&) = delete;
  SparePermits& operator=(const SparePermits&) = delete;
  int taken() const { return taken_; }

 private:
  WorkPermits* permits_;
  int taken_;
  WorkerLoad::Clock::time_point acquired_;
};

}  // namespace visloc::server
