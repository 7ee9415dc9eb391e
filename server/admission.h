#pragma once
// Admission control: a server that cannot take another robot without making the robots it has
// late refuses the new session (RESOURCE_EXHAUSTED, with the reason and what to do) instead of
// slowing everyone. The rule projects the workers' busy fraction with one more session:
//   - the load committed: each session's own measured cost (its frame rate times its frames'
//     CPU time, in cores), a session too new to have one costed as the median session; and at
//     least what the workers' window measured (worker_load.h: their wall-clock time on frames,
//     which also sees the cores taken by the link's threads and anything else);
//   - plus the newcomer, costed as the median session;
// and refuses when that passes max_busy_fraction: past about nine tenths of two cores, queues
// grow and every robot's latency with them (docs/capacity.md), so the limit keeps headroom.
// Counting sessions too new to be measured keeps a group of robots arriving at once from all
// being admitted on the load before them. Frames already waiting long for a worker
// (max_wait_p95_ms) refuse too. With nothing measured yet, a session is admitted.

#include <string>
#include <vector>

#include "server/worker_load.h"

namespace visloc::server {

struct AdmissionOptions {
  double max_busy_fraction = 0.8;  // 0: the load is not checked (only --max-sessions).
  double max_wait_p95_ms = 20.0;
  int64_t min_frames = 100;  // A window with fewer frames says too little about the load.
  bool enabled() const { return max_busy_fraction > 0.0; }
  void Check() const;  // Throws UsageError naming the bad option.
};

struct AdmissionDecision {
  bool admit = true;
  double projected_busy_fraction = 0.0;  // With one more session.
  std::string why;                       // When refused: the load, the limit, what to do.
};

// `session_loads`: each open session's measured cost (cores; negative for a session not
// measured yet), not counting the newcomer. `workers`: the cores the engine runs on.
AdmissionDecision DecideAdmission(const WorkerLoadStats& load, int workers,
                                  const std::vector<double>& session_loads,
                                  const AdmissionOptions& options);

}  // namespace visloc::server
