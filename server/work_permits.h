#pragma once
// A counting semaphore: the worker pool's size as permits. Sessions wait here for their turn to
// run the engine, so N sessions share the machine's cores instead of oversubscribing them.

#include <algorithm>
#include <condition_variable>
#include <mutex>

namespace visloc::server {

class WorkPermits {
 public:
  explicit WorkPermits(int permits) : permits_(permits), free_(permits) {}
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
};

// Holds one permit for its scope.
class WorkPermit {
 public:
  explicit WorkPermit(WorkPermits* permits) : permits_(permits) { permits_->Acquire(); }
  ~WorkPermit() { permits_->Release(); }
  WorkPermit(const WorkPermit&) = delete;
  WorkPermit& operator=(const WorkPermit&) = delete;

 private:
  WorkPermits* permits_;
};

// Holds, for its scope, up to `wanted` further permits that are free when it starts: the idle
// cores a rig session's frame may use for its cameras side by side, never waited for (a busy
// server runs the frame's cameras one after the other on its one permit).
class SparePermits {
 public:
  SparePermits(WorkPermits* permits, int wanted)
      : permits_(permits), taken_(wanted > 0 ? permits->TryAcquire(wanted) : 0) {}
  ~SparePermits() {
    for (int i = 0; i < taken_; ++i) permits_->Release();
  }
  SparePermits(const SparePermits&) = delete;
  SparePermits& operator=(const SparePermits&) = delete;
  int taken() const { return taken_; }

 private:
  WorkPermits* permits_;
  int taken_;
};

}  // namespace visloc::server
