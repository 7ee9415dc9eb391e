#include "core/util/worker_pool.h"

#include <algorithm>
#include <chrono>

#include "core/util/check.h"
#include "core/util/parallel.h"

namespace visloc {
namespace {

// Calls done() until it is true or kSpinMicroseconds have passed; whether it became true.
template <typename Done>
bool SpinUntil(const Done& done, std::chrono::steady_clock::time_point deadline) {
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::yield();  // Another runnable thread on this core goes first.
  }
  return true;
}

// The same for kSpinMicroseconds from now.
template <typename Done>
bool SpinUntil(const Done& done) {
  return SpinUntil(done, std::chrono::steady_clock::now() +
                             std::chrono::microseconds(WorkerPool::kSpinMicroseconds));
}

}  // namespace

WorkerPool::WorkerPool(int helpers) : helpers_(std::max(0, helpers)), seats_(helpers_) {}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  for (std::thread& thread : threads_) thread.join();
}

void WorkerPool::Start() {
  for (int helper = 0; helper < helpers_; ++helper) {
    threads_.emplace_back([this, helper] { HelperLoop(helper); });
  }
}

void WorkerPool::ExpectJob(std::chrono::steady_clock::time_point when,
                           std::chrono::microseconds lead, std::chrono::microseconds grace) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    expectation_ = {when, lead, grace};
    ++expectation_id_;
  }
  wake_.notify_all();  // Helpers asleep without a deadline take this one's.
}

WorkerPool::ExpectationStats WorkerPool::expectation_stats() const {
  return {expected_wakes_.load(), expected_met_.load(), expected_missed_.load()};
}

bool WorkerPool::LookForJob(uint32_t seen, HelperSeat* seat) {
  seat->cpu.store(CurrentCpu(), std::memory_order_relaxed);
  return stop_ || generation_.load(std::memory_order_acquire) != seen;
}

void WorkerPool::AwaitJob(std::unique_lock<std::mutex>& lock, uint32_t seen, uint64_t* honored,
                          HelperSeat* seat) {
  const auto job_or_stop = [&] { return stop_ || generation_.load() != seen; };
  while (!job_or_stop()) {
    if (*honored == expectation_id_) {
      wake_.wait(lock);  // Until a job, stop or a new expectation.
      continue;
    }
    const Expectation expected = expectation_;
    if (std::chrono::steady_clock::now() < expected.when - expected.lead) {
      wake_.wait_until(lock, expected.when - expected.lead);
      continue;
    }
    // The window is open: look for the job without sleeping until it comes or the window ends.
    *honored = expectation_id_;
    ++expected_wakes_;
    lock.unlock();
    const bool met =
        SpinUntil([&] { return LookForJob(seen, seat); }, expected.when + expected.grace);
    ++(met ? expected_met_ : expected_missed_);
    lock.lock();
  }
}

void WorkerPool::HelperLoop(int helper) {
  HelperSeat& seat = seats_[helper];
  seat.cpus = CpuSet::OfThisThread();
  // Published after cpus: a caller reads them once it sees the id (MoveHelpersOffThisCpu).
  seat.thread_id.store(CurrentThreadId(), std::memory_order_release);
  uint32_t seen = 0;
  uint64_t honored = 0;  // The last expectation this helper woke for.
  for (;;) {
    SpinUntil([&] { return LookForJob(seen, &seat); });
    const std::function<void(int)>* body = nullptr;
    int parts = 0;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      AwaitJob(lock, seen, &honored, &seat);
      if (stop_) return;
      seen = generation_.load();
      if (helper < job_helpers_) {
        body = body_;
        parts = parts_;
      }
    }
    // Moved off a caller's core and running elsewhere now: its own cores again, for later.
    if (seat.moved.exchange(false)) seat.cpus.ApplyTo();
    if (body == nullptr) continue;  // That job has ended already, or is not this helper's.
    if (helper_delay_.count() > 0) std::this_thread::sleep_for(helper_delay_);
    RunParts(seen, *body, parts);
  }
}

void WorkerPool::RunParts(uint32_t generation, const std::function<void(int part)>& body,
                          int parts) {
  for (;;) {
    uint64_t claim = claim_.load(std::memory_order_acquire);
    do {
      if (static_cast<uint32_t>(claim >> 32) != generation ||
          static_cast<int>(claim & 0xffffffffu) >= parts) {
        return;  // Another job's, or every part of this one is taken.
      }
    } while (!claim_.compare_exchange_weak(claim, claim + 1, std::memory_order_acq_rel));
    RunPart(static_cast<int>(claim & 0xffffffffu), body, parts);
  }
}

void WorkerPool::RunPart(int part, const std::function<void(int part)>& body, int parts) {
  try {
    body(part);
  } catch (...) {
    errors_[part] = std::current_exception();  // Read by the caller after every part is done.
  }
  if (done_parts_.fetch_add(1, std::memory_order_acq_rel) + 1 == parts) {
    std::lock_guard<std::mutex> lock(mutex_);  // The caller checks done_parts_ under it.
    done_.notify_one();
  }
}

void WorkerPool::WaitForParts(int parts) {
  const auto all_done = [&] { return done_parts_.load(std::memory_order_acquire) == parts; };
  if (SpinUntil(all_done)) return;
  std::unique_lock<std::mutex> lock(mutex_);
  done_.wait(lock, all_done);
}

void WorkerPool::Ranges(int n, int threads, const std::function<void(int begin, int end)>& fn) {
  if (n <= 0) return;
  const int parts = std::clamp(std::min(threads, helpers_ + 1), 1, n);
  const auto range = [&](int part) {
    const auto [begin, end] = PartRange(n, part, parts);
    fn(begin, end);
  };
  if (parts == 1) return range(0);
  Run(parts, parts - 1, range);
}

void WorkerPool::ForEachClaimed(int n, int threads, const std::function<void(int i)>& fn) {
  if (n <= 0) return;
  const int helpers = std::clamp(threads - 1, 0, std::min(helpers_, n - 1));
  if (helpers == 0) {
    for (int i = 0; i < n; ++i) fn(i);
    return;
  }
  Run(n, helpers, fn);
}

void WorkerPool::Run(int parts, int helpers, const std::function<void(int part)>& body) {
  VISLOC_CHECK(!busy_.exchange(true), "WorkerPool: one caller at a time");
  if (threads_.empty()) Start();
  errors_.assign(parts, nullptr);
  uint32_t generation = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    body_ = &body;
    parts_ = parts;
    job_helpers_ = helpers;
    done_parts_.store(0, std::memory_order_relaxed);
    generation = generation_.load(std::memory_order_relaxed) + 1;
    // Part 0 is the caller's, claimed before any helper can look.
    claim_.store((uint64_t{generation} << 32) | 1u, std::memory_order_relaxed);
    generation_.store(generation, std::memory_order_release);
  }
  wake_.notify_all();
  MoveHelpersOffThisCpu(helpers);
  RunPart(0, body, parts);
  RunParts(generation, body, parts);  // Whatever no helper has started.
  WaitForParts(parts);
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

void WorkerPool::MoveHelpersOffThisCpu(int helpers) {
  const int cpu = CurrentCpu();
  if (cpu < 0) return;
  for (int helper = 0; helper < helpers; ++helper) {
    HelperSeat& seat = seats_[helper];
    const int64_t thread_id = seat.thread_id.load(std::memory_order_acquire);
    if (thread_id == 0 || seat.cpu.load(std::memory_order_relaxed) != cpu) continue;
    // Marked first: the helper, once moved, may run and look before this thread goes on.
    seat.moved = true;
    if (KeepThreadOffCpu(thread_id, seat.cpus, cpu)) {
      seat.cpu = -1;  // Not known until it looks again.
      ++helpers_moved_;
    }
  }
}

bool WorkerPool::PinHelperForTest(int helper, int cpu) {
  HelperSeat& seat = seats_.at(helper);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  int64_t thread_id = 0;  // Set once the helper's thread has started.
  while ((thread_id = seat.thread_id.load(std::memory_order_acquire)) == 0 &&
         std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  if (thread_id == 0 || !CpuSet::Single(cpu).ApplyTo(thread_id)) return false;
  seat.cpu = cpu;  // The only core it can be on now.
  return true;
}

void WorkerPool::ForEach(int n, int threads, const std::function<void(int i)>& fn) {
  Ranges(n, threads, [&](int begin, int end) {
    for (int i = begin; i < end; ++i) fn(i);
  });
}

}  // namespace visloc
