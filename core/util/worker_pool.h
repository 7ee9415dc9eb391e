#pragma once
// Helper threads that stay for the life of their owner, for work split several times per frame:
// a rig session's cameras extract, predict and match side by side three times a frame.
// ParallelRanges starts and joins a thread per call; on a virtual machine a new thread on an
// idle core starts tens to hundreds of microseconds late, which a 1.4 ms frame cannot afford
// three times. Here helpers wait on a condition variable between frames and spin briefly
// (kSpinMicroseconds) after each job, when the next part of the same frame usually follows.

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace visloc {

class WorkerPool {
 public:
  // Up to `helpers` threads beside the caller's, started on the first call that needs them.
  explicit WorkerPool(int helpers);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  // As ParallelRanges: fn(begin, end) on contiguous ranges covering [0, n), at most `threads`
  // of them (and at most helpers + 1), the first on the calling thread; returns when all have,
  // rethrowing the exception of the lowest range that threw. One caller at a time.
  void Ranges(int n, int threads, const std::function<void(int begin, int end)>& fn);
  // fn(i) for every i of [0, n), over Ranges.
  void ForEach(int n, int threads, const std::function<void(int i)>& fn);

  int helpers() const { return helpers_; }

  // How long a helper keeps looking for the next job before it sleeps, and the caller for the
  // helpers' end before it does.
  static constexpr int64_t kSpinMicroseconds = 200;

 private:
  void Start();
  void HelperLoop(int part);
  void WaitForHelpers();

  const int helpers_;
  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable wake_;  // A new job, or stop.
  std::condition_variable done_;  // The job's helpers are done.
  // The job: body(part) for parts 1 .. parts_ - 1, set under mutex_ before generation_ moves.
  const std::function<void(int part)>* body_ = nullptr;
  int parts_ = 0;
  std::vector<std::exception_ptr> errors_;
  std::atomic<uint64_t> generation_{0};
  std::atomic<int> pending_{0};  // The job's helpers still running.
  std::atomic<bool> stop_{false};
  std::atomic<bool> busy_{false};  // A caller is in Ranges (checks "one caller at a time").
};

}  // namespace visloc
