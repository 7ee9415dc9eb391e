#include "core/util/thread_priority.h"

#include <sys/resource.h>

#include <algorithm>
#include <cerrno>

#include "core/util/cpu_placement.h"

namespace visloc {
namespace {

// setpriority(PRIO_PROCESS, tid) sets one thread's nice on Linux (POSIX would set the process's).
id_t ThisThreadsId() { return static_cast<id_t>(CurrentThreadId()); }

}  // namespace

int ThisThreadsNice() {
  errno = 0;
  const int nice = getpriority(PRIO_PROCESS, ThisThreadsId());
  return errno == 0 ? nice : 0;
}

int LowerThisThreadsPriority(int increment) {
  const int target = std::min(19, ThisThreadsNice() + std::max(0, increment));
  setpriority(PRIO_PROCESS, ThisThreadsId(), target);  // Fails only in exotic sandboxes: harmless.
  return ThisThreadsNice();
}

}  // namespace visloc
