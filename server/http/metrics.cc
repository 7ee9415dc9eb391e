#include "server/http/metrics.h"

#include <algorithm>
#include <chrono>
#include <map>
#include <sstream>

#include "core/util/strings.h"

namespace visloc::server {
namespace {

// Label values escaped as the format asks (backslash, quote, newline).
std::string Escaped(const std::string& value) {
  std::string out;
  for (char c : value) {
    if (c == '\\' || c == '"') out += '\\';
    out += c == '\n' ? 'n' : c;
  }
  return out;
}

class Exposition {
 public:
  // Starts a metric family: its HELP and TYPE lines.
  Exposition& Family(const std::string& name, const std::string& type, const std::string& help) {
    out_ << "# HELP " << name << " " << help << "\n# TYPE " << name << " " << type << "\n";
    return *this;
  }
  Exposition& Sample(const std::string& name, double value,
                     const std::vector<std::pair<std::string, std::string>>& labels = {}) {
    out_ << name;
    if (!labels.empty()) {
      out_ << "{";
      for (size_t i = 0; i < labels.size(); ++i) {
        out_ << (i ? "," : "") << labels[i].first << "=\"" << Escaped(labels[i].second) << "\"";
      }
      out_ << "}";
    }
    out_ << " " << FormatNumber(value) << "\n";
    return *this;
  }
  std::string str() const { return out_.str(); }

 private:
  static std::string FormatNumber(double value) {
    std::ostringstream s;
    s.precision(17);
    s << value;
    return s.str();
  }
  std::ostringstream out_;
};

void SessionMetrics(const ServerStatus& status, Exposition& e) {
  e.Family("visloc_sessions_open", "gauge", "Localize streams open now.")
      .Sample("visloc_sessions_open", static_cast<double>(status.sessions.size()));
  e.Family("visloc_sessions_max", "gauge", "Concurrent sessions the server accepts.")
      .Sample("visloc_sessions_max", status.max_sessions);
  e.Family("visloc_sessions_lost", "gauge",
           "Open sessions whose last answered frame had no pose (lost or not yet localized).");
  int lost = 0;
  for (const SessionStatus& s : status.sessions) lost += !s.has_pose && s.frames > 0;
  e.Sample("visloc_sessions_lost", lost);
  // For alerts on a robot lost for long (its id stays out of the labels): the longest time any
  // open session has been without a pose.
  double longest_s = 0;
  const auto now = std::chrono::system_clock::now();
  for (const SessionStatus& s : status.sessions) {
    if (s.frames > 0 && s.without_pose_since) {
      longest_s = std::max(longest_s,
                           std::chrono::duration<double>(now - *s.without_pose_since).count());
    }
  }
  e.Family("visloc_session_without_pose_seconds_max", "gauge",
           "The longest time an open session has gone without a pose (0: all have one).")
      .Sample("visloc_session_without_pose_seconds_max", longest_s);
  e.Family("visloc_sessions_started_total", "counter", "Sessions started, by map.");
  for (const auto& [map, counts] : status.counters.maps) {
    e.Sample("visloc_sessions_started_total", static_cast<double>(counts.sessions), {{"map", map}});
  }
  e.Family("visloc_sessions_idle_closed_total", "counter",
           "Sessions closed because no frame came for the idle timeout.")
      .Sample("visloc_sessions_idle_closed_total", status.idle_sessions_closed);
}

void FrameMetrics(const ServerStatus& status, Exposition& e) {
  e.Family("visloc_frames_total", "counter",
           "Frames that arrived, by map and outcome (a tracking status, skipped or error).");
  for (const auto& [map, counts] : status.counters.maps) {
    for (const auto& [outcome, frames] : counts.frames) {
      e.Sample("visloc_frames_total", static_cast<double>(frames),
               {{"map", map}, {"status", outcome}});
    }
  }
  e.Family("visloc_relocalizations_total", "counter",
           "Frames that searched the map by appearance, by map and whether a pose was found.");
  for (const auto& [map, counts] : status.counters.maps) {
    e.Sample("visloc_relocalizations_total", static_cast<double>(counts.relocalizations_found),
             {{"map", map}, {"result", "found"}});
    e.Sample("visloc_relocalizations_total",
             static_cast<double>(counts.relocalizations - counts.relocalizations_found),
             {{"map", map}, {"result", "not_found"}});
  }
  const FrameCounters& c = status.counters;
  e.Family("visloc_frame_server_seconds", "histogram",
           "Server time of an answered frame: decoding, the engine and its wait for a worker.");
  for (size_t b = 0; b < std::size(FrameCounters::kSecondsBuckets); ++b) {
    e.Sample("visloc_frame_server_seconds_bucket", static_cast<double>(c.seconds_buckets[b]),
             {{"le", FormatFixed(FrameCounters::kSecondsBuckets[b], 3)}});
  }
  e.Sample("visloc_frame_server_seconds_bucket", static_cast<double>(c.seconds_count),
           {{"le", "+Inf"}})
      .Sample("visloc_frame_server_seconds_sum", c.seconds_sum)
      .Sample("visloc_frame_server_seconds_count", static_cast<double>(c.seconds_count));
}

void MapAndWorkerMetrics(const ServerStatus& status, Exposition& e) {
  e.Family("visloc_maps_loaded", "gauge", "Maps held in memory.")
      .Sample("visloc_maps_loaded", static_cast<double>(status.maps.size()));
  e.Family("visloc_map_memory_bytes", "gauge", "Memory of each loaded map.");
  for (const LoadedMapStatus& map : status.maps) {
    e.Sample("visloc_map_memory_bytes", static_cast<double>(map.memory_bytes), {{"map", map.name}});
  }
  e.Family("visloc_map_users", "gauge", "Sessions and relocalizations holding each loaded map.");
  for (const LoadedMapStatus& map : status.maps) {
    e.Sample("visloc_map_users", map.users, {{"map", map.name}});
  }
  e.Family("visloc_map_loads_total", "counter", "Map loads from the maps folder.")
      .Sample("visloc_map_loads_total", status.map_loads);
  e.Family("visloc_map_load_failures_total", "counter",
           "Map files that failed to load when a session or relocalization asked for them.")
      .Sample("visloc_map_load_failures_total", status.map_load_failures);
  e.Family("visloc_map_cache_hits_total", "counter", "Map requests served from memory.")
      .Sample("visloc_map_cache_hits_total", status.map_cache_hits);
  e.Family("visloc_rpcs_total", "counter", "Finished RPCs by full method name and status code.");
  for (const auto& [key, calls] : status.rpcs) {
    e.Sample("visloc_rpcs_total", static_cast<double>(calls),
             {{"method", key.first}, {"code", key.second}});
  }
  e.Family("visloc_workers", "gauge", "Frames the engine processes at once at most.")
      .Sample("visloc_workers", status.workers);
  e.Family("visloc_workers_busy", "gauge", "Frames in the engine now.")
      .Sample("visloc_workers_busy", status.workers_busy);
  const WorkerLoadStats& load = status.worker_load;
  e.Family("visloc_worker_busy_ratio", "gauge",
           "The workers' time on frames over the last window (0..1).")
      .Sample("visloc_worker_busy_ratio", load.busy_fraction);
  e.Family("visloc_worker_wait_p95_seconds", "gauge",
           "How long frames waited for a free worker over the last window, 95th percentile.")
      .Sample("visloc_worker_wait_p95_seconds", load.wait_p95_ms / 1000.0);
  e.Family("visloc_admission_busy_limit_ratio", "gauge",
           "Admission control's busy limit: new sessions are refused past it (0: off).")
      .Sample("visloc_admission_busy_limit_ratio", status.admit_busy_fraction);
  e.Family("visloc_admission_projected_busy_ratio", "gauge",
           "What one more session would make the workers' busy fraction.")
      .Sample("visloc_admission_projected_busy_ratio", status.projected_busy_fraction);
  e.Family("visloc_sessions_refused_at_capacity_total", "counter",
           "Sessions refused (RESOURCE_EXHAUSTED) because the server was at capacity.")
      .Sample("visloc_sessions_refused_at_capacity_total",
              static_cast<double>(status.sessions_refused_at_capacity));
}

}  // namespace

std::string PrometheusText(const ServerStatus& status, const std::string& version) {
  Exposition e;
  e.Family("visloc_build_info", "gauge", "The server's version, as a label; always 1.")
      .Sample("visloc_build_info", 1, {{"version", version}});
  SessionMetrics(status, e);
  FrameMetrics(status, e);
  MapAndWorkerMetrics(status, e);
  return e.str();
}

}  // namespace visloc::server
