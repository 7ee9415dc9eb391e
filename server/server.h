#pragma once
// visloc-server's composition root: one ServerConfig in, the running server out. It owns the map
// cache, the services (Localization, MapAdmin, Mapping, Fleet, grpc.health.v1, reflection), the
// transport (listening address, TLS, keepalive, message limits) and the janitor that unloads idle
// maps, and answers Status() with a snapshot of what it is doing. Flags and signals are main.cc's.

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "server/auth.h"
#include "server/fleet_service.h"
#include "server/http/http_endpoint.h"
#include "server/localizability_cache.h"
#include "server/localization_service.h"
#include "server/map_admin_service.h"
#include "server/map_cache.h"
#include "server/mapping_service.h"
#include "server/rpc_counters.h"
#include "server/server_status.h"

namespace visloc::server {

struct ServerConfig {
  std::string maps_dir;
  std::string listen = "127.0.0.1:50051";  // Port 0 picks a free port.
  int max_sessions = 64;
  // Admission control (admission.h): a new session is refused when one more would take the
  // workers past this busy fraction (0: off), or frames already wait longer than this for one.
  double admit_busy = 0.8;
  double admit_wait_ms = 20.0;
  int idle_unload_s = 300;
  int64_t map_memory_mib = 0;  // Per map; 0: no bound.
  double drain_s = 5.0;
  int64_t max_upload_mib = 2048;
  std::string tls_cert, tls_key, tls_client_ca;  // PEM files.
  std::string tokens;                            // Tokens file; empty: no tokens.
  double max_frame_rate_hz = 0.0;                // Per session; 0: no limit.
  bool allow_remote = false;                     // Listen beyond loopback without tokens.
  bool maps_read_only = false;
  int threads = 0;  // Frames processed at once; 0: one per core.
  double session_idle_timeout_s = 30.0;
  // Link keepalive (gRPC's keepalive guidance): clients may ping this often without being
  // struck off; the server pings quiet connections to find dead ones.
  double keepalive_min_ping_interval_s = 5.0;
  int keepalive_ping_strikes = 2;
  double keepalive_time_s = 20.0, keepalive_timeout_s = 10.0;
  double max_connection_idle_s = 0.0, max_connection_age_s = 0.0;  // 0: unlimited.
  std::string http;  // HOST:PORT of the probes and metrics (http/http_endpoint.h); empty: none.
  // Mapping over the link (mapping_service.h): jobs at once, each job's threads, its frames.
  int max_mapping_jobs = 1;
  int mapping_threads = 1;
  int max_mapping_frames = 20000;
  int64_t max_mapping_memory_mib = 2048;  // What one job's mapper may hold.
  double mapping_resume_s = 30.0;  // A broken mapping stream's job waits this long to resume.
  // Where mapping jobs are kept as they arrive, to outlive the server; empty: MAPS/.mapping-jobs.
  std::string mapping_spool;
  int64_t mapping_min_free_mib = 1024;  // Disk the spool leaves free; jobs beyond it are refused.

  // Throws UsageError naming the flag of the first bad value.
  void Check() const;
  // The worker count `threads` means on this machine.
  int Workers() const;
};

class Server {
 public:
  // Checks the config, reads the tokens and certificates, and starts serving. Throws UsageError
  // for a bad config, InputError for unreadable files or an address that cannot be listened on.
  explicit Server(const ServerConfig& config);
  // Stops at once if Drain() was not called.
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  // The address listened on, with the port chosen for port 0.
  const std::string& address() const { return address_; }
  // The HTTP endpoint's address (port chosen for port 0); empty without --http.
  std::string http_address() const { return http_ ? http_->address() : ""; }
  ServerStatus Status() const;
  // The maps of the folder with their sizes (each file described once per version of it).
  std::vector<MapSummary> Maps() const;
  // A map from above, at most `max_points` points and `max_keyframes` keyframe centres.
  MapTopView TopView(const std::string& name, size_t max_points = 20000,
                     size_t max_keyframes = 4000);
  // Health turns NOT_SERVING (load balancers stop sending robots here), no new calls are
  // accepted, open streams get the config's drain period, then everything stops.
  void Drain();

 private:
  void LogStart(int stale_temporaries_removed) const;
  // Empty when ready to take robots; else why not (for /readyz).
  std::string Readiness() const;

  ServerConfig config_;
  TokenAuth auth_;
  MapCache maps_;
  LocalizabilityCache localizability_;
  LocalizationService localization_;
  MapAdminService admin_;
  MappingService mapping_;
  FleetService fleet_;
  RpcCounters rpcs_;
  std::unique_ptr<grpc::Server> grpc_server_;
  std::string address_;
  // Maps() remembers each file's description by its size and modification time.
  struct DescribedMap {
    uint64_t bytes = 0;
    std::filesystem::file_time_type modified;
    MapSummary summary;
  };
  mutable std::mutex described_mutex_;
  mutable std::map<std::string, DescribedMap> described_;
  std::atomic<bool> stopping_{false};
  std::atomic<bool> draining_{false};
  std::thread janitor_;
  std::unique_ptr<HttpEndpoint> http_;  // Last: it reads everything above.
};

}  // namespace visloc::server
