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

}  // namespace

AdmissionDecision DecideAdmission(const WorkerLoadStats& load, int workers,
                                  const std::vector<double>& session_loads,
                                  const AdmissionOptions& options) {
  workers = std::max(1, workers);
  std::vector<double> measured;
  double measured_sum = 0.0;
  for (const double cores : session_loads) {
    if (cores < 0.0) continue;
    measured.push_back(cores);
    measured_sum += cores;
  }
  const int sessions = static_cast<int>(session_loads.size());
  // What the process spends beyond its sessions' frames, per core of theirs: the link's threads
  // receiving and parsing each frame, the replies. Bounded: a mapping job's core is not a
  // robot's.
  const double overhead = measured_sum > 0.0 && load.process_cpu_cores > 0.0
                              ? std::clamp(load.process_cpu_cores / measured_sum, 1.0, kMaxOverhead)
                              : 1.0;
  // A session's cost in cores: the median measured one, else the window's load shared out.
  const double per_session = !measured.empty()
                                 ? overhead * Median(measured)
                                 : (sessions > 0 ? load.busy_fraction * workers / sessions : 0.0);
  const double committed =
      overhead * measured_sum + per_session * static_cast<double>(sessions - measured.size());
  const double busy_now =
      std::max({load.busy_fraction, load.process_cpu_cores / workers, committed / workers});
  AdmissionDecision decision;
  decision.projected_busy_fraction = busy_now + per_session / workers;
  if (!options.enabled() || (load.frames < options.min_frames && measured.empty())) {
    return decision;
  }
  const std::string measured_text =
      StrCat("its workers (", workers, ") were ", FormatFixed(100 * load.busy_fraction, 0),
             "% busy over the last ", FormatFixed(load.window_s, 0), " s, the process used ",
             FormatFixed(load.process_cpu_cores, 2), " cores, and its ", sessions,
             " sessions take ", FormatFixed(100 * busy_now, 0), "% of them (",
             FormatFixed(per_session, 3), " cores a session); frames waited ",
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
