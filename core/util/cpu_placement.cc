#include "core/util/cpu_placement.h"

#if defined(__linux__)
#include <sys/syscall.h>
#include <unistd.h>
#endif

namespace visloc {

#if defined(__linux__)

int CurrentCpu() { return sched_getcpu(); }

int64_t CurrentThreadId() { return static_cast<int64_t>(syscall(SYS_gettid)); }

CpuSet CpuSet::OfThisThread() {
  CpuSet cpus;
  if (sched_getaffinity(0, sizeof(cpus.set_), &cpus.set_) != 0) CPU_ZERO(&cpus.set_);
  return cpus;
}

CpuSet CpuSet::Single(int cpu) {
  CpuSet one;
  CPU_ZERO(&one.set_);
  if (cpu >= 0 && cpu < CPU_SETSIZE) CPU_SET(cpu, &one.set_);
  return one;
}

bool CpuSet::ApplyTo(int64_t thread_id) const {
  return thread_id >= 0 && count() > 0 &&
         sched_setaffinity(static_cast<pid_t>(thread_id), sizeof(set_), &set_) == 0;
}

CpuSet CpuSet::Without(int cpu) const {
  CpuSet others = *this;
  if (cpu >= 0 && cpu < CPU_SETSIZE) CPU_CLR(cpu, &others.set_);
  return others;
}

int CpuSet::count() const { return CPU_COUNT(&set_); }

bool CpuSet::contains(int cpu) const {
  return cpu >= 0 && cpu < CPU_SETSIZE && CPU_ISSET(cpu, &set_);
}

bool KeepThreadOffCpu(int64_t thread_id, const CpuSet& allowed, int cpu) {
  // The calling thread's id is never 0 on Linux: 0 would name the caller itself.
  return thread_id > 0 && allowed.contains(cpu) && allowed.Without(cpu).ApplyTo(thread_id);
}

#else

int CurrentCpu() { return -1; }
int64_t CurrentThreadId() { return 0; }
CpuSet CpuSet::OfThisThread() { return {}; }
CpuSet CpuSet::Single(int) { return {}; }
bool CpuSet::ApplyTo(int64_t) const { return false; }
CpuSet CpuSet::Without(int) const { return {}; }
int CpuSet::count() const { return 0; }
bool CpuSet::contains(int) const { return false; }
bool KeepThreadOffCpu(int64_t, const CpuSet&, int) { return false; }

#endif

}  // namespace visloc
