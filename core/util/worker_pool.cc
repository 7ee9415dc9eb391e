#include "core/util/worker_pool.h"

#include <algorithm>
#include <chrono>

#include "core/util/check.h"
#include "core/util/parallel.h"

namespace visloc {
namespace {

// Calls done() until it is true or kSpinMicroseconds have passed; whether it became true.
template <typename Done>
bool SpinUntil(const Done& done) {
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::microseconds(WorkerPool::kSpinMicroseconds);
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::yield();  // Another runnable thread on this core goes first.
  }
  return true;
}

}  // namespace

WorkerPool::WorkerPool(int helpers) : helpers_(std::max(0, helpers)) {}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  for (std::thread& thread : threads_) thread.join();
}

void WorkerPool::Start() {
  for (int part = 1; part <= helpers_; ++part) {
    threads_.emplace_back([this, part] { HelperLoop(part); });
  }
}

void WorkerPool::HelperLoop(int part) {
  uint64_t seen = 0;
  for (;;) {
    SpinUntil([&] { return stop_ || generation_.load(std::memory_order_acquire) != seen; });
    const std::function<void(int)>* body = nullptr;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] { return stop_ || generation_.load() != seen; });
      if (stop_) return;
      seen = generation_.load();
      if (part < parts_) body = body_;
    }
    if (body == nullptr) continue;  // Not needed for this job.
    try {
      (*body)(part);
    } catch (...) {
      errors_[part] = std::current_exception();  // Read by the caller after pending_ is 0.
    }
    if (pending_.fetch_sub(1, std::memory_order_acq_rel) == 1) {
      std::lock_guard<std::mutex> lock(mutex_);  // The caller checks pending_ under it.
      done_.notify_one();
    }
  }
}

void WorkerPool::WaitForHelpers() {
  if (SpinUntil([&] { return pending_.load(std::memory_order_acquire) == 0; })) return;
  std::unique_lock<std::mutex> lock(mutex_);
  done_.wait(lock, [&] { return pending_.load(std::memory_order_acquire) == 0; });
}

void WorkerPool::Ranges(int n, int threads, const std::function<void(int begin, int end)>& fn) {
  if (n <= 0) return;
  const int parts = std::clamp(std::min(threads, helpers_ + 1), 1, n);
  const auto range = [&](int part) {
    const auto [begin, end] = PartRange(n, part, parts);
    fn(begin, end);
  };
  if (parts == 1) return range(0);
  VISLOC_CHECK(!busy_.exchange(true), "WorkerPool::Ranges called by two threads at once");
  if (threads_.empty()) Start();
  const std::function<void(int)> body = range;
  errors_.assign(parts, nullptr);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    body_ = &body;
    parts_ = parts;
    pending_.store(parts - 1, std::memory_order_relaxed);
    generation_.fetch_add(1, std::memory_order_release);
  }
  wake_.notify_all();
  try {
    range(0);
  } catch (...) {
    errors_[0] = std::current_exception();
  }
  WaitForHelpers();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    body_ = nullptr;
    parts_ = 0;
  }
  busy_ = false;
  for (const std::exception_ptr& error : errors_) {
    if (error) std::rethrow_exception(error);
  }
}

void WorkerPool::ForEach(int n, int threads, const std::function<void(int i)>& fn) {
  Ranges(n, threads, [&](int begin, int end) {
    for (int i = begin; i < end; ++i) fn(i);
  });
}

}  // namespace visloc
