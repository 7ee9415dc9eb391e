#include "server/admission.h"

#include <algorithm>

#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/strings.h"

namespace visloc::server {

void AdmissionOptions::Check() const {
  if (!(max_busy_fraction >= 0.0 && max_busy_fraction <= 1.0)) {
    throw UsageError(StrCat("--admit-busy ", max_busy_fraction, ": a fraction, 0 (off) to 1"));
  }
  if (!(max_wait_p95_ms > 0.0)) {
    throw UsageError(StrCat("--admit-wait-ms ", max_wait_p95_ms, ": must be positive"));
  }
}

namespace {

// A session's share of the process's overhead is at most this many times its own frames' CPU.
constexpr double kMaxOverhead = 3.0;

double Median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  const size_t n = values.size();
  return n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

// From the sessions' own CPU costs: committed cores with one more session, over the workers.
// `per_session` (cores) is what the newcomer is taken to cost.
double CpuProjection(const WorkerLoadStats& load, int workers,
                     const std::vector<SessionLoad>& sessions, double* per_session) {
  std::vector<double> measured;
  double measured_sum = 0.0;
  for (const SessionLoad& s : sessions) {
    if (s.cpu_cores < 0.0) continue;
    measured.push_back(s.cpu_cores);
    measured_sum += s.cpu_cores;
  }
  // What the process spends beyond its sessions' frames, per core of theirs: the link's threads
  // receiving and parsing each frame, the replies. Bounded: a mapping job's core is not a
  // robot's.
  const double overhead = measured_sum > 0.0 && load.process_cpu_cores > 0.0
                              ? std::clamp(load.process_cpu_cores / measured_sum, 1.0, kMaxOverhead)
                              : 1.0;
  *per_session = measured.empty() ? 0.0 : overhead * Median(measured);
  const double committed = overhead * measured_sum +
                           *per_session * static_cast<double>(sessions.size() - measured.size());
  return std::max(load.process_cpu_cores, committed) / workers + *per_session / workers;
}

// From the workers' window: its busy fraction spread over the sessions as much of the window as
// each was there for (a session that arrived 2 s into a 10 s window is a fifth in it), then
// every session whole and one more. It sees what CPU times miss: cores taken by the link's
// threads and anything else, and frames slowed by that contention.
double WindowProjection(const WorkerLoadStats& load, const std::vector<SessionLoad>& sessions,
                        double* sessions_in_window) {
  *sessions_in_window = 0.0;
  for (const SessionLoad& s : sessions) {
    *sessions_in_window += std::clamp(s.age_s / std::max(1e-3, load.window_s), 0.0, 1.0);
  }
  // Less than half a session's worth says too little to scale up.
  if (*sessions_in_window < 0.5) return load.busy_fraction;
  return load.busy_fraction * static_cast<double>(sessions.size() + 1) / *sessions_in_window;
}

}  // namespace

AdmissionDecision DecideAdmission(const WorkerLoadStats& load, int workers,
                                  const std::vector<SessionLoad>& sessions,
                                  const AdmissionOptions& options) {
  workers = std::max(1, workers);
  double per_session_cores = 0.0, sessions_in_window = 0.0;
  const double by_cpu = CpuProjection(load, workers, sessions, &per_session_cores);
  const double by_window = WindowProjection(load, sessions, &sessions_in_window);
  AdmissionDecision decision;
  decision.projected_busy_fraction = std::max(by_cpu, by_window);
  const bool measured = load.frames >= options.min_frames || per_session_cores > 0.0;
  if (!options.enabled() || !measured) return decision;
  const std::string measured_text =
      StrCat("its workers (", workers, ") were ", FormatFixed(100 * load.busy_fraction, 0),
             "% busy over the last ", FormatFixed(load.window_s, 0), " s with ", sessions.size(),
             " sessions (", FormatFixed(sessions_in_window, 1),
             " of them over that time), the process used ", FormatFixed(load.process_cpu_cores, 2),
             " cores (", FormatFixed(per_session_cores, 3), " a session); frames waited ",
             FormatFixed(load.wait_p95_ms, 1), " ms for a worker (p95)");
  std::string over;
  if (decision.projected_busy_fraction > options.max_busy_fraction) {
    over =
        StrCat("one more session would take them to ",
               FormatFixed(100 * decision.projected_busy_fraction, 0), "%, over the ",
               FormatFixed(100 * options.max_busy_fraction, 0), "% that keeps its robots on time");
  } else if (load.wait_p95_ms > options.max_wait_p95_ms) {
    over = StrCat("over the ", FormatFixed(options.max_wait_p95_ms, 1), " ms wait it allows");
  } else {
    return decision;
  }
  decision.admit = false;
  decision.why = StrCat("server at capacity: ", measured_text, "; ", over,
                        ". Retry in a few seconds, or on another replica");
  return decision;
}

}  // namespace visloc::server
