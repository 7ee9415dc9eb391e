#pragma once
// Which core a thread runs on, and moving another thread off one (Linux; elsewhere, no-ops).
//
// Why a worker pool needs it: a helper that spins for its next job (WorkerPool) is a running
// task, so when the caller is woken (a frame's arrival, the end of a part it waited for), the
// scheduler may put the caller on the helper's core. The two then share one core while the other
// idles: the idle core does not pull the helper over, since a task that just ran is "cache hot",
// and the caller, preferred over a task that yielded, runs the whole frame alone. Through the
// server at 15 fps on 2 cores this held a rig frame's helper off 30-40% of its parts. The caller
// that finds a helper on its own core moves the helper off it (KeepThreadOffCpu); the helper,
// once running elsewhere, takes back its own set of cores (CpuSet::ApplyTo).

#include <cstdint>

#if defined(__linux__)
#include <sched.h>
#endif

namespace visloc {

// The core the calling thread is on now; -1 where unknown.
int CurrentCpu();

// The kernel's id of the calling thread (what KeepThreadOffCpu takes); 0 where unknown.
int64_t CurrentThreadId();

// A set of cores a thread may run on.
class CpuSet {
 public:
  // The calling thread's own set (its process's, a cgroup's or taskset's limit).
  static CpuSet OfThisThread();
  // The one core `cpu`.
  static CpuSet Single(int cpu);
  // Makes it the set of thread `thread_id` (0: the calling thread); false, changing nothing,
  // for an empty set or when the system refused.
  bool ApplyTo(int64_t thread_id = 0) const;
  // This set but `cpu`.
  CpuSet Without(int cpu) const;
  int count() const;
  bool contains(int cpu) const;

 private:
#if defined(__linux__)
  cpu_set_t set_{};
#endif
};

// Restricts thread `thread_id` (CurrentThreadId of that thread) to the cores of `allowed` but
// `cpu`, which moves it to another core at once if it was on `cpu`, running or waiting to run.
// False, changing nothing, when no core would be left or the system refused.
bool KeepThreadOffCpu(int64_t thread_id, const CpuSet& allowed, int cpu);

}  // namespace visloc
