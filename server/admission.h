#pragma once
// Admission control: a server that cannot take another robot without making the robots it has
// late refuses the new session (RESOURCE_EXHAUSTED, with the reason and what to do) instead of
// slowing everyone. It projects the workers' busy fraction with one more session, two ways, and
// takes the larger:
//   - from the sessions' own costs: each one's frame rate times its frames' CPU time on a
//     worker (cores), scaled by the process's overhead (the cores the whole process uses over
//     its sessions' own, at most 3: the link's threads), a session too new to be measured
//     costed as the median one, and the newcomer as the median one;
//   - from the workers' window (worker_load.h): its busy fraction spread over the sessions as
//     much of the window as each was there for, then every session whole and one more. Wall
//     time sees what CPU times miss: the cores taken by anything else, and contention.
// and refuses when that passes max_busy_fraction: past about nine tenths of two cores, queues
// grow and every robot's latency with them (docs/admission.md), so the limit keeps headroom.
// Counting sessions too new for the window at their whole cost keeps robots that arrive
// together, or retry together, from all being admitted on the load before them. Frames
// already waiting long for a worker (max_wait_p95_ms) refuse too. With nothing measured yet, a
// session is admitted.

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

// An open session, as admission weighs it.
struct SessionLoad {
  double cpu_cores = -1.0;  // Its measured cost (SessionStatus::cpu_load); negative: not yet.
  double age_s = 0.0;       // Since it started.
};

// `sessions`: the sessions open now, not counting the newcomer. `workers`: the cores the engine
// runs on.
AdmissionDecision DecideAdmission(const WorkerLoadStats& load, int workers,
                                  const std::vector<SessionLoad>& sessions,
                                  const AdmissionOptions& options);

}  // namespace visloc::server
