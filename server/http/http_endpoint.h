#pragma once
// visloc-server's HTTP side (`--http HOST:PORT`), through cpp-httplib (Debian's
// libcpp-httplib-dev): the probes and the metrics, read from the same ServerStatus snapshot as
// the Fleet service, so they never disagree.
//
//   GET /healthz   200 while the process serves (for liveness probes; no token needed)
//   GET /readyz    200 when the maps folder is readable and gRPC is listening and not draining,
//                  503 with the reason otherwise (readiness probes; no token needed)
//   GET /metrics   the Prometheus text format (metrics.h); with tokens, a bearer token of any
//                  role ("Authorization: Bearer TOKEN"), as the gRPC API asks
//   GET /          the operator's page (page/index.html, built into the server): the maps, a
//                  map's top view with each live robot, and per robot its recent figures
//   GET /api/sessions, /api/maps, /api/maps/NAME/view   its data (operator_api.h; token as
//                  for /metrics), and /api/events: the sessions pushed as Server-Sent Events
//                  5 times a second (at most kMaxEventStreams watchers at once)
// With the server's TLS certificate and key, it serves HTTPS. Answers carry no server paths.

#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "core/localization/localizability.h"
#include "server/auth.h"
#include "server/server_status.h"

namespace httplib {
class Server;
}

namespace visloc::server {

struct HttpOptions {
  std::string listen;             // HOST:PORT; port 0 picks a free port.
  std::string tls_cert, tls_key;  // PEM files; both empty: plain HTTP.
  std::string version;            // For visloc_build_info.
};

// Where the answers come from; each is called per request, from the endpoint's threads.
struct HttpSources {
  std::function<ServerStatus()> status;
  std::function<std::string()> readiness;  // Empty when ready, else why not.
  std::function<std::vector<MapSummary>()> maps;
  // Throws NotFoundError for an unknown map, InputError for one that does not load.
  std::function<MapTopView(const std::string& name)> top_view;
  // The map's localizability grid at the default options (LocalizabilityCache); throws as
  // top_view does, and InputError for a map with no level frame.
  std::function<std::shared_ptr<const LocalizabilityReport>(const std::string& name)>
      localizability;
  // The mapping jobs (running and recently ended) with their maps so far.
  std::function<std::vector<MappingJobView>()> mapping_jobs;
};

class HttpEndpoint {
 public:
  static constexpr int kMaxEventStreams = 4;
  static constexpr int kEventIntervalMs = 200;

  // `auth` must outlive the endpoint. Throws InputError when it cannot listen.
  HttpEndpoint(const HttpOptions& options, HttpSources sources, const TokenAuth* auth);
  ~HttpEndpoint();
  HttpEndpoint(const HttpEndpoint&) = delete;
  HttpEndpoint& operator=(const HttpEndpoint&) = delete;

  // HOST:PORT listened on (the port chosen for port 0).
  const std::string& address() const { return address_; }

 private:
  void Route(const HttpOptions& options);
  void RouteOperatorPage();

  HttpSources sources_;
  const TokenAuth* auth_;
  std::atomic<int> event_streams_{0};
  std::atomic<bool> stopping_{false};
  std::unique_ptr<httplib::Server> http_;
  std::string address_;
  std::thread thread_;
};

}  // namespace visloc::server
