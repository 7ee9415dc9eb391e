// visloc-server: the localization service for a fleet of robots (product.md).
//
//   visloc-server --maps DIR [--listen 127.0.0.1:50051] [--tls-cert F --tls-key F]
//                 [--tls-client-ca F] [--tokens F] [--threads N] [--max-sessions N]
//                 [--admit-busy F] [--admit-wait-ms MS]
//                 [--max-frame-rate-hz HZ] [--session-idle-timeout-s S] [--keepalive-*-s ...]
//
// Serves Localization, MapAdmin, grpc.health.v1 and server reflection. Prints
// "listening on ADDRESS" once ready (with port 0, the port chosen). SIGTERM or SIGINT drains:
// no new streams, open ones get a grace period, then the process exits 0. The server itself is
// server/server.h; this file is its flags and signals.

#include <signal.h>

#include <cstdio>
#include <iostream>

#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/memory.h"
#include "core/util/version.h"
#include "server/log.h"
#include "server/server.h"

namespace visloc::server {
namespace {

void AddFlags(ArgParser& parser, ServerConfig* c) {
  parser.AddFlag("maps", &c->maps_dir, "folder of map files NAME.db", /*required=*/true);
  parser.AddFlag("listen", &c->listen, "address:port (port 0 picks a free port)");
  parser.AddFlag("http", &c->http,
                 "HOST:PORT for /healthz, /readyz and /metrics (Prometheus); off unless given");
  parser.AddFlag("max-sessions", &c->max_sessions, "concurrent Localize streams");
  parser.AddFlag("admit-busy", &c->admit_busy,
                 "refuse a new session (RESOURCE_EXHAUSTED) when one more would take the "
                 "workers past this busy fraction over the last 10 s; 0: off");
  parser.AddFlag("admit-wait-ms", &c->admit_wait_ms,
                 "refuse a new session while frames wait longer than this for a worker (p95)");
  parser.AddFlag("idle-unload-s", &c->idle_unload_s, "unload maps idle this long");
  parser.AddFlag("map-memory-mib", &c->map_memory_mib,
                 "memory bound per map: larger maps are served paged, their points read per "
                 "keyframe region on demand (0: no bound)");
  parser.AddFlag("drain-s", &c->drain_s, "grace period for open streams at shutdown");
  parser.AddFlag("max-upload-mib", &c->max_upload_mib, "largest map upload accepted, MiB");
  parser.AddFlag("max-mapping-jobs", &c->max_mapping_jobs,
                 "maps built at once from streamed stereo runs (visloc map build --server); 0: "
                 "none");
  parser.AddFlag("mapping-threads", &c->mapping_threads,
                 "threads of each mapping job (features, stereo matching)");
  parser.AddFlag("max-mapping-frames", &c->max_mapping_frames,
                 "stereo frames one mapping job takes");
  parser.AddFlag("max-mapping-memory-mib", &c->max_mapping_memory_mib,
                 "memory one mapping job's mapper may hold (features, stereo matches, points), "
                 "MiB; frames beyond it are refused and the run may be ended to publish");
  parser.AddFlag("mapping-resume-s", &c->mapping_resume_s,
                 "a mapping job whose link broke waits this long for its client to resume it, "
                 "keeping its map so far (0: dropped at once)");
  parser.AddFlag("mapping-spool", &c->mapping_spool,
                 "folder where mapping jobs are kept as their frames arrive, so that a restarted "
                 "server (or a replica on the same folder) takes them up again");
  parser.SetDefaultText("mapping-spool", "MAPS/.mapping-jobs");
  parser.AddFlag("mapping-min-free-mib", &c->mapping_min_free_mib,
                 "disk the mapping spool leaves free: jobs and frames beyond it are refused");
  parser.AddFlag("tls-cert", &c->tls_cert, "serve TLS with this certificate chain (PEM)");
  parser.AddFlag("tls-key", &c->tls_key, "the certificate's private key (PEM)");
  parser.AddFlag("tls-client-ca", &c->tls_client_ca,
                 "mutual TLS: require client certificates signed by this CA (PEM)");
  parser.AddFlag("max-frame-rate-hz", &c->max_frame_rate_hz,
                 "frames per second one session may send; more are answered SKIPPED (0: no limit)");
  parser.AddFlag("tokens", &c->tokens,
                 "bearer tokens file: 'TOKEN localize|admin' per line, each token at least 16 "
                 "characters");
  parser.AddSwitch("allow-remote", &c->allow_remote,
                   "listen beyond loopback without tokens (trusted networks only)");
  parser.AddSwitch("maps-read-only", &c->maps_read_only,
                   "never change the maps folder (a replica of a shared folder another server "
                   "writes): map upload, delete and rename are refused");
  parser.AddFlag("threads", &c->threads, "frames processed at once across sessions");
  parser.SetDefaultText("threads", "0: one per core");
  parser.AddFlag("session-idle-timeout-s", &c->session_idle_timeout_s,
                 "close a session with no frame for this many seconds and free its slot (0: off)");
  parser.AddFlag("keepalive-min-ping-interval-s", &c->keepalive_min_ping_interval_s,
                 "seconds: clients pinging more often than this are struck (see ping strikes)");
  parser.AddFlag("keepalive-ping-strikes", &c->keepalive_ping_strikes,
                 "too-frequent pings tolerated before the connection is closed");
  parser.AddFlag("keepalive-time-s", &c->keepalive_time_s,
                 "seconds of silence before the server pings a client's connection");
  parser.AddFlag("keepalive-timeout-s", &c->keepalive_timeout_s,
                 "seconds to wait for a ping's answer before closing the connection as dead");
  parser.AddFlag("max-connection-idle-s", &c->max_connection_idle_s,
                 "close connections without calls for this many seconds (0: never)");
  parser.AddFlag("max-connection-age-s", &c->max_connection_age_s,
                 "close connections older than this many seconds, after a grace of --drain-s "
                 "(0: never)");
  // The names before they said their units (0.1.0 and earlier).
  for (const auto& [former, name] :
       {std::pair{"max-upload-mb", "max-upload-mib"},
        {"max-frame-rate", "max-frame-rate-hz"},
        {"session-idle-timeout", "session-idle-timeout-s"},
        {"keepalive-min-ping-interval", "keepalive-min-ping-interval-s"},
        {"keepalive-time", "keepalive-time-s"},
        {"keepalive-timeout", "keepalive-timeout-s"},
        {"max-connection-idle", "max-connection-idle-s"},
        {"max-connection-age", "max-connection-age-s"}}) {
    parser.AddFormerName(former, name);
  }
}

int Run(int argc, char** argv) {
  if (argc == 2 && std::string(argv[1]) == "--version") {
    std::cout << "visloc-server " << VislocVersion() << "\n";
    return 0;
  }
  ServerConfig config;
  ArgParser parser("visloc-server",
                   "Serves visual localization (Localization.Localize / Relocalize) and map "
                   "management (MapAdmin) over gRPC, with grpc.health.v1 and reflection. "
                   "'visloc-server --version' prints its version.");
  AddFlags(parser, &config);
  if (!parser.Parse(std::vector<std::string>(argv + 1, argv + argc), std::cout)) return 0;
  // Block the shutdown signals in every thread the server starts; this one waits for them.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  Server server(config);
  std::printf("listening on %s\n", server.address().c_str());
  if (!server.http_address().empty()) std::printf("http on %s\n", server.http_address().c_str());
  std::fflush(stdout);
  int signal_number = 0;
  sigwait(&signals, &signal_number);
  Log("server_draining", {{"signal", signal_number == SIGTERM ? "SIGTERM" : "SIGINT"},
                          {"open_sessions", std::to_string(server.Status().sessions.size())}});
  server.Drain();
  return 0;
}

}  // namespace
}  // namespace visloc::server

int main(int argc, char** argv) {
  visloc::KeepFreedMemoryForReuse();
  visloc::RunOpenCvOnCallingThread();  // Sessions run in parallel, one worker per core.
  try {
    return visloc::server::Run(argc, argv);
  } catch (const visloc::UsageError& e) {
    std::fprintf(stderr, "visloc-server: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "visloc-server: %s\n", e.what());
    return 1;
  }
}
