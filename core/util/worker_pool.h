#pragma once
// Helper threads that stay for the life of their owner, for work split several times per frame:
// a rig session's cameras extract, predict and match side by side three times a frame.
// ParallelRanges starts and joins a thread per call; on a virtual machine a new thread on an
// idle core starts tens to hundreds of microseconds late, which a 1.4 ms frame cannot afford
// three times. Here helpers wait on a condition variable between frames and spin briefly
// (kSpinMicroseconds) after each job, when the next part of the same frame usually follows.
// A job's parts are claimed, not assigned: the caller runs the first, then takes any part no
// helper has started. A helper that wakes late (its core busy with another session, or taken
// by the host) then costs the frame nothing beyond running that part on the caller, where a
// part waiting for its helper would add the helper's whole delay to the frame's latency.
// A caller that finds a helper on its own core moves the helper to another (cpu_placement.h:
// the scheduler can leave the two sharing one core while the other idles).

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

#include "core/util/cpu_placement.h"

namespace visloc {

class WorkerPool {
 public:
  // Up to `helpers` threads beside the caller's, started on the first call that needs them.
  explicit WorkerPool(int helpers);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  // As ParallelRanges: fn(begin, end) on contiguous ranges covering [0, n), at most `threads`
  // of them (and at most helpers + 1), the first on the calling thread and each other on the
  // first thread to claim it (a helper, or the caller once its own is done); returns when all
  // have, rethrowing the exception of the lowest range that threw. One caller at a time.
  void Ranges(int n, int threads, const std::function<void(int begin, int end)>& fn);
  // fn(i) for every i of [0, n), over Ranges.
  void ForEach(int n, int threads, const std::function<void(int i)>& fn);
  // fn(i) for every i of [0, n), each i a part of its own claimed in order by the first of up
  // to `threads` threads (the caller and threads - 1 helpers) to come for it: a thread that ends
  // its part early takes the next, so unequal parts balance (a late helper's camera beside the
  // caller's, and the work that does not wait for either after them).
  void ForEachClaimed(int n, int threads, const std::function<void(int i)>& fn);

  // The next job is expected at `when`: a helper asleep then wakes `lead` before it and looks
  // for the job until `grace` after it, so the job does not wait for the helper's wake (a rig
  // session's next frame, ArrivalPredictor). A later call replaces an earlier one's.
  void ExpectJob(std::chrono::steady_clock::time_point when, std::chrono::microseconds lead,
                 std::chrono::microseconds grace);

  // What the expectations came to: a helper woke for one (wakes), and a job then came while it
  // looked (met) or the window ended without one (missed). Counted per helper.
  struct ExpectationStats {
    int64_t wakes = 0;
    int64_t met = 0;
    int64_t missed = 0;
  };
  ExpectationStats expectation_stats() const;

  // Times a caller found a helper on its own core and moved it to another.
  int64_t helpers_moved() const { return helpers_moved_.load(); }

  int helpers() const { return helpers_; }

  // How long a helper keeps looking for the next job before it sleeps, and the caller for the
  // helpers' end before it does.
  static constexpr int64_t kSpinMicroseconds = 200;

  // Fault injection for tests: each helper sleeps this long after it wakes for a job, before it
  // claims a part (a helper whose core is busy elsewhere).
  void set_helper_delay_for_test(std::chrono::microseconds delay) { helper_delay_ = delay; }
  // For tests: confines helper `helper` to core `cpu`, as the scheduler could leave it, once its
  // thread has started (waits up to 5 s). False if it did not start or the system refused.
  bool PinHelperForTest(int helper, int cpu);

 private:
  void Start();
  void HelperLoop(int helper);
  // body(part) for every part of [0, parts), claimed by the caller and up to `helpers` helpers.
  void Run(int parts, int helpers, const std::function<void(int part)>& body);
  // Claims and runs parts of job `generation` until none is left unclaimed.
  void RunParts(uint32_t generation, const std::function<void(int part)>& body, int parts);
  // Runs one claimed part, keeping its exception for the caller, and counts it done.
  void RunPart(int part, const std::function<void(int part)>& body, int parts);
  void WaitForParts(int parts);
  // Moves each of the job's first `helpers` helpers that is on the calling thread's core now
  // (or was last, asleep) to another of its cores.
  void MoveHelpersOffThisCpu(int helpers);
  struct HelperSeat;
  // One look of a spinning helper: notes the core it is on (for MoveHelpersOffThisCpu), and
  // whether a job after `seen`, or stop, has come.
  bool LookForJob(uint32_t seen, HelperSeat* seat);
  // Under `lock`, until a job after `seen` or stop: asleep, but awake over the window of an
  // expectation the helper has not yet looked out for (`honored`, its id).
  void AwaitJob(std::unique_lock<std::mutex>& lock, uint32_t seen, uint64_t* honored,
                HelperSeat* seat);

  const int helpers_;
  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable wake_;  // A new job, or stop.
  std::condition_variable done_;  // The job's parts are all done.
  // The job: body(part) for every part, set under mutex_ before generation_ moves.
  const std::function<void(int part)>* body_ = nullptr;
  int parts_ = 0;
  int job_helpers_ = 0;  // Helpers with an index below this take part in the job.
  std::vector<std::exception_ptr> errors_;
  std::atomic<uint32_t> generation_{0};
  // The job's generation (high 32 bits) and its next unclaimed part (low 32): a helper holding
  // an earlier job's body can never claim a part of a later job.
  std::atomic<uint64_t> claim_{0};
  std::atomic<int> done_parts_{0};  // The job's parts finished, on any thread.
  std::chrono::microseconds helper_delay_{0};
  // The next job's expectation (under mutex_), and its id: 0 for none yet.
  struct Expectation {
    std::chrono::steady_clock::time_point when;
    std::chrono::microseconds lead{0}, grace{0};
  };
  Expectation expectation_;
  uint64_t expectation_id_ = 0;
  std::atomic<int64_t> expected_wakes_{0}, expected_met_{0}, expected_missed_{0};
  // Where each helper is: its thread's id and own cores (set once it starts), the core it last
  // looked for a job on, and whether a caller has moved it (it takes back its cores then).
  struct HelperSeat {
    std::atomic<int64_t> thread_id{0};
    CpuSet cpus;
    std::atomic<int> cpu{-1};
    std::atomic<bool> moved{false};
  };
  std::vector<HelperSeat> seats_;
  std::atomic<int64_t> helpers_moved_{0};
  std::atomic<bool> stop_{false};
  std::atomic<bool> busy_{false};  // A caller is in Ranges (checks "one caller at a time").
};

}  // namespace visloc
