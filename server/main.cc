// visloc-server: the localization service for a fleet of robots (product.md).
//
//   visloc-server --maps DIR [--listen 127.0.0.1:50051] [--tls-cert F --tls-key F]
//                 [--tls-client-ca F] [--tokens F] [--threads N] [--max-sessions N]
//                 [--max-frame-rate HZ] [--session-idle-timeout S] [--keepalive-* ...]
//
// Serves Localization, MapAdmin, grpc.health.v1 and server reflection. Prints
// "listening on ADDRESS" once ready (with port 0, the port chosen). SIGTERM or SIGINT drains:
// no new streams, open ones get a grace period, then the process exits 0.

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <grpcpp/resource_quota.h>
#include <signal.h>

#include <chrono>
#include <cstdio>
#include <iostream>
#include <thread>

#include "core/features/features.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/memory.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"
#include "core/util/version.h"
#include "server/auth.h"
#include "server/localization_service.h"
#include "server/log.h"
#include "server/map_admin_service.h"

namespace visloc::server {
namespace {

struct ServerArgs {
  std::string maps_dir;
  std::string listen = "127.0.0.1:50051";
  int max_sessions = 64;
  int idle_unload_s = 300;
  int64_t map_memory_mib = 0;  // 0: no bound.
  double drain_s = 5.0;
  int64_t max_upload_mb = 2048;
  std::string tls_cert, tls_key, tls_client_ca, tokens;
  double max_frame_rate_hz = 0.0;  // Per session; 0: no limit.
  bool allow_remote = false;
  bool maps_read_only = false;
  int threads = 0;
  double session_idle_timeout_s = 30.0;
  // Link keepalive (gRPC's keepalive guidance): clients may ping this often without being
  // struck off; the server pings quiet connections to find dead ones.
  double keepalive_min_ping_interval_s = 5.0;
  int keepalive_ping_strikes = 2;
  double keepalive_time_s = 20.0, keepalive_timeout_s = 10.0;
  double max_connection_idle_s = 0.0, max_connection_age_s = 0.0;  // 0: unlimited.
};

// The transport's keepalive and connection-lifetime arguments from the flags.
void SetLinkArguments(const ServerArgs& args, grpc::ServerBuilder* builder) {
  const auto ms = [](double s) { return static_cast<int>(s * 1000); };
  builder->AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS,
                              ms(args.keepalive_min_ping_interval_s));
  builder->AddChannelArgument(GRPC_ARG_HTTP2_MAX_PING_STRIKES, args.keepalive_ping_strikes);
  builder->AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  builder->AddChannelArgument(GRPC_ARG_KEEPALIVE_TIME_MS, ms(args.keepalive_time_s));
  builder->AddChannelArgument(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, ms(args.keepalive_timeout_s));
  if (args.max_connection_idle_s > 0) {
    builder->AddChannelArgument(GRPC_ARG_MAX_CONNECTION_IDLE_MS, ms(args.max_connection_idle_s));
  }
  if (args.max_connection_age_s > 0) {
    builder->AddChannelArgument(GRPC_ARG_MAX_CONNECTION_AGE_MS, ms(args.max_connection_age_s));
    // Streams open at the age limit get this long to finish before the connection closes.
    builder->AddChannelArgument(GRPC_ARG_MAX_CONNECTION_AGE_GRACE_MS, ms(args.drain_s));
  }
}

void CheckLinkArguments(const ServerArgs& args) {
  const auto positive = [](double v, const char* flag) {
    if (!(v > 0 && v < 86400)) throw UsageError(StrCat(flag, " must be in (0, 86400) seconds"));
  };
  if (!(args.session_idle_timeout_s >= 0 && args.session_idle_timeout_s < 86400)) {
    throw UsageError("--session-idle-timeout must be in [0, 86400) seconds (0: off)");
  }
  positive(args.keepalive_min_ping_interval_s, "--keepalive-min-ping-interval");
  positive(args.keepalive_time_s, "--keepalive-time");
  positive(args.keepalive_timeout_s, "--keepalive-timeout");
  if (args.keepalive_ping_strikes < 0) throw UsageError("--keepalive-ping-strikes must be >= 0");
  if (!(args.max_connection_idle_s >= 0) || !(args.max_connection_age_s >= 0)) {
    throw UsageError("--max-connection-idle and --max-connection-age must be >= 0 (0: off)");
  }
  if (args.map_memory_mib < 0 || args.map_memory_mib > (int64_t{1} << 24)) {
    throw UsageError("--map-memory-mib must be 0 (no bound) to 16777216");
  }
}

std::shared_ptr<grpc::ServerCredentials> Credentials(const ServerArgs& args) {
  if (args.tls_cert.empty() != args.tls_key.empty()) {
    throw UsageError("--tls-cert and --tls-key go together");
  }
  if (!args.tls_client_ca.empty() && args.tls_cert.empty()) {
    throw UsageError("--tls-client-ca needs --tls-cert and --tls-key");
  }
  if (args.tls_cert.empty()) return grpc::InsecureServerCredentials();
  // Mutual TLS when a client CA is given: a client without a certificate signed by it is
  // refused during the handshake, before any RPC (and before tokens are looked at).
  grpc::SslServerCredentialsOptions options(
      args.tls_client_ca.empty() ? GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE
                                 : GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY);
  if (!args.tls_client_ca.empty()) options.pem_root_certs = ReadFileBytes(args.tls_client_ca);
  options.pem_key_cert_pairs.push_back({ReadFileBytes(args.tls_key), ReadFileBytes(args.tls_cert)});
  return grpc::SslServerCredentials(options);
}

bool IsLoopback(const std::string& address) {
  return address.rfind("127.", 0) == 0 || address.rfind("localhost:", 0) == 0 ||
         address.rfind("[::1]:", 0) == 0;
}

int Run(int argc, char** argv) {
  if (argc == 2 && std::string(argv[1]) == "--version") {
    std::cout << "visloc-server " << VislocVersion() << "\n";
    return 0;
  }
  ServerArgs args;
  ArgParser parser("visloc-server",
                   "Serves visual localization (Localization.Localize / Relocalize) and map "
                   "management (MapAdmin) over gRPC, with grpc.health.v1 and reflection. "
                   "'visloc-server --version' prints its version.");
  parser.AddFlag("maps", &args.maps_dir, "folder of map files NAME.db", /*required=*/true);
  parser.AddFlag("listen", &args.listen, "address:port (port 0 picks a free port)");
  parser.AddFlag("max-sessions", &args.max_sessions, "concurrent Localize streams");
  parser.AddFlag("idle-unload-s", &args.idle_unload_s, "unload maps idle this long");
  parser.AddFlag("map-memory-mib", &args.map_memory_mib,
                 "memory bound per map: larger maps are served paged, their points read per "
                 "keyframe region on demand (0: no bound)");
  parser.AddFlag("drain-s", &args.drain_s, "grace period for open streams at shutdown");
  parser.AddFlag("max-upload-mb", &args.max_upload_mb, "largest map upload accepted");
  parser.AddFlag("tls-cert", &args.tls_cert, "serve TLS with this certificate chain (PEM)");
  parser.AddFlag("tls-key", &args.tls_key, "the certificate's private key (PEM)");
  parser.AddFlag("tls-client-ca", &args.tls_client_ca,
                 "mutual TLS: require client certificates signed by this CA (PEM)");
  parser.AddFlag("max-frame-rate", &args.max_frame_rate_hz,
                 "frames per second one session may send; more are answered SKIPPED (0: no limit)");
  parser.AddFlag("tokens", &args.tokens,
                 "bearer tokens file: 'TOKEN localize|admin' per line, each token at least 16 "
                 "characters");
  parser.AddSwitch("allow-remote", &args.allow_remote,
                   "listen beyond loopback without tokens (trusted networks only)");
  parser.AddSwitch("maps-read-only", &args.maps_read_only,
                   "never change the maps folder (a replica of a shared folder another server "
                   "writes): map upload, delete and rename are refused");
  parser.AddFlag("threads", &args.threads, "frames processed at once across sessions");
  parser.SetDefaultText("threads", "0: one per core");
  parser.AddFlag("session-idle-timeout", &args.session_idle_timeout_s,
                 "close a session with no frame for this many seconds and free its slot (0: off)");
  parser.AddFlag("keepalive-min-ping-interval", &args.keepalive_min_ping_interval_s,
                 "seconds: clients pinging more often than this are struck (see ping strikes)");
  parser.AddFlag("keepalive-ping-strikes", &args.keepalive_ping_strikes,
                 "too-frequent pings tolerated before the connection is closed");
  parser.AddFlag("keepalive-time", &args.keepalive_time_s,
                 "seconds of silence before the server pings a client's connection");
  parser.AddFlag("keepalive-timeout", &args.keepalive_timeout_s,
                 "seconds to wait for a ping's answer before closing the connection as dead");
  parser.AddFlag("max-connection-idle", &args.max_connection_idle_s,
                 "close connections without calls for this many seconds (0: never)");
  parser.AddFlag("max-connection-age", &args.max_connection_age_s,
                 "close connections older than this many seconds, after a grace of --drain-s "
                 "(0: never)");
  if (!parser.Parse(std::vector<std::string>(argv + 1, argv + argc), std::cout)) return 0;
  CheckLinkArguments(args);
  if (args.max_sessions < 1) throw UsageError("--max-sessions must be at least 1");
  if (!IsLoopback(args.listen) && args.tokens.empty() && !args.allow_remote) {
    throw UsageError("without --tokens the server listens on loopback only (got " + args.listen +
                     "; --allow-remote overrides)");
  }
  if (args.threads < 0) throw UsageError("--threads must not be negative");
  if (!(args.max_frame_rate_hz >= 0)) throw UsageError("--max-frame-rate must not be negative");
  const TokenAuth auth = args.tokens.empty() ? TokenAuth() : TokenAuth::FromFile(args.tokens);
  const auto credentials = Credentials(args);

  // Block the shutdown signals in every thread; one thread waits for them.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  MapCache maps(args.maps_dir, std::chrono::seconds(args.idle_unload_s),
                static_cast<size_t>(args.map_memory_mib) << 20);
  // A read-only replica must not touch the folder: the temporaries in it may be another
  // server's uploads in progress (whose process ids mean nothing in this one's namespace).
  const int stale =
      args.maps_read_only ? 0 : mapstore::MapDirectory(args.maps_dir).RemoveStaleTemporaries();
  ServiceLimits limits;
  limits.max_sessions = args.max_sessions;
  limits.max_frame_rate_hz = args.max_frame_rate_hz;
  limits.session_idle_timeout =
      std::chrono::milliseconds(static_cast<int64_t>(args.session_idle_timeout_s * 1000));
  // The per-frame engine work runs on at most this many threads at once: the machine's cores.
  limits.workers = args.threads > 0
                       ? args.threads
                       : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  LocalizationService localization(&maps, limits, &auth);
  MapAdminOptions admin_options;
  admin_options.max_upload_bytes = static_cast<uint64_t>(args.max_upload_mb) << 20;
  admin_options.read_only = args.maps_read_only;
  MapAdminService admin(&maps, admin_options, &auth);

  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort(args.listen, credentials, &port);
  // gRPC sets SO_REUSEPORT by default: a second server on a port in use would start, and the
  // kernel would share new connections out between the two at random. The address is ours alone.
  builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  // The sync server gives each call a thread, and a Localize stream keeps its thread for its
  // life (mostly waiting on the network); room for every session plus admin calls.
  grpc::ResourceQuota quota("visloc-server");
  quota.SetMaxThreads(args.max_sessions + 16);
  builder.SetResourceQuota(quota);
  builder.RegisterService(&localization);
  builder.RegisterService(&admin);
  builder.SetMaxReceiveMessageSize(64 << 20);  // A raw 4096x4096 frame is 16 MiB.
  SetLinkArguments(args, &builder);
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server || port == 0) {
    throw InputError("cannot listen on " + args.listen +
                     ": the address is in use (another visloc-server?) or not this machine's");
  }
  grpc::HealthCheckServiceInterface* health = server->GetHealthCheckService();
  for (const char* service : {"visloc.v1.Localization", "visloc.v1.MapAdmin"}) {
    health->SetServingStatus(service, true);
  }
  const std::string bound =
      args.listen.substr(0, args.listen.rfind(':')) + ":" + std::to_string(port);
  Log("server_start",
      {{"listen", bound},
       {"maps", args.maps_dir},
       {"maps_read_only", args.maps_read_only ? "yes" : "no"},
       {"max_sessions", std::to_string(args.max_sessions)},
       {"map_memory_mib", args.map_memory_mib ? std::to_string(args.map_memory_mib) : "unbounded"},
       {"workers", std::to_string(limits.workers)},
       {"tls", args.tls_cert.empty()        ? "off"
               : args.tls_client_ca.empty() ? "on"
                                            : "mutual"},
       {"max_frame_rate_hz", FormatFixed(args.max_frame_rate_hz, 1)},
       {"session_idle_timeout_s", FormatFixed(args.session_idle_timeout_s, 1)},
       {"keepalive_min_ping_interval_s", FormatFixed(args.keepalive_min_ping_interval_s, 1)},
       {"tokens", auth.enabled() ? "on" : "off"},
       {"stale_temporaries_removed", std::to_string(stale)}});
  std::printf("listening on %s\n", bound.c_str());
  std::fflush(stdout);

  std::atomic<bool> stopping{false};
  std::thread janitor([&] {
    while (!stopping) {
      std::this_thread::sleep_for(std::chrono::milliseconds(500));
      maps.UnloadIdle();
    }
  });
  int signal_number = 0;
  sigwait(&signals, &signal_number);
  Log("server_draining", {{"signal", signal_number == SIGTERM ? "SIGTERM" : "SIGINT"},
                          {"open_sessions", std::to_string(localization.active_sessions())}});
  health->SetServingStatus(false);  // Load balancers stop sending new robots here.
  server->Shutdown(std::chrono::system_clock::now() +
                   std::chrono::milliseconds(static_cast<int64_t>(args.drain_s * 1000)));
  server->Wait();
  stopping = true;
  janitor.join();
  Log("server_stop", {{"maps_loaded", std::to_string(maps.stats().loads)}});
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
