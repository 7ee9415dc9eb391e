#include "server/server.h"

#include "mapping/site_alignment.h"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>
#include <grpcpp/resource_quota.h>

#include <chrono>
#include <filesystem>

#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"
#include "core/util/version.h"
#include "proto/geometry_convert.h"
#include "server/client_errors.h"
#include "server/log.h"

namespace visloc::server {
namespace {

bool IsLoopback(const std::string& address) {
  return address.rfind("127.", 0) == 0 || address.rfind("localhost:", 0) == 0 ||
         address.rfind("[::1]:", 0) == 0;
}

void CheckLinkConfig(const ServerConfig& config) {
  const auto positive = [](double v, const char* flag) {
    if (!(v > 0 && v < 86400)) throw UsageError(StrCat(flag, " must be in (0, 86400) seconds"));
  };
  if (!(config.session_idle_timeout_s >= 0 && config.session_idle_timeout_s < 86400)) {
    throw UsageError("--session-idle-timeout-s must be in [0, 86400) seconds (0: off)");
  }
  positive(config.keepalive_min_ping_interval_s, "--keepalive-min-ping-interval-s");
  positive(config.keepalive_time_s, "--keepalive-time-s");
  positive(config.keepalive_timeout_s, "--keepalive-timeout-s");
  if (config.keepalive_ping_strikes < 0) {
    throw UsageError("--keepalive-ping-strikes must be >= 0");
  }
  if (!(config.max_connection_idle_s >= 0) || !(config.max_connection_age_s >= 0)) {
    throw UsageError("--max-connection-idle-s and --max-connection-age-s must be >= 0 (0: off)");
  }
}

// The transport's keepalive and connection-lifetime arguments.
void SetLinkArguments(const ServerConfig& config, grpc::ServerBuilder* builder) {
  const auto ms = [](double s) { return static_cast<int>(s * 1000); };
  builder->AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS,
                              ms(config.keepalive_min_ping_interval_s));
  builder->AddChannelArgument(GRPC_ARG_HTTP2_MAX_PING_STRIKES, config.keepalive_ping_strikes);
  builder->AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  builder->AddChannelArgument(GRPC_ARG_KEEPALIVE_TIME_MS, ms(config.keepalive_time_s));
  builder->AddChannelArgument(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, ms(config.keepalive_timeout_s));
  if (config.max_connection_idle_s > 0) {
    builder->AddChannelArgument(GRPC_ARG_MAX_CONNECTION_IDLE_MS, ms(config.max_connection_idle_s));
  }
  if (config.max_connection_age_s > 0) {
    builder->AddChannelArgument(GRPC_ARG_MAX_CONNECTION_AGE_MS, ms(config.max_connection_age_s));
    // Streams open at the age limit get this long to finish before the connection closes.
    builder->AddChannelArgument(GRPC_ARG_MAX_CONNECTION_AGE_GRACE_MS, ms(config.drain_s));
  }
}

std::shared_ptr<grpc::ServerCredentials> Credentials(const ServerConfig& config) {
  if (config.tls_cert.empty()) return grpc::InsecureServerCredentials();
  // Mutual TLS when a client CA is given: a client without a certificate signed by it is
  // refused during the handshake, before any RPC (and before tokens are looked at).
  grpc::SslServerCredentialsOptions options(
      config.tls_client_ca.empty() ? GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE
                                   : GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY);
  if (!config.tls_client_ca.empty()) options.pem_root_certs = ReadFileBytes(config.tls_client_ca);
  options.pem_key_cert_pairs.push_back(
      {ReadFileBytes(config.tls_key), ReadFileBytes(config.tls_cert)});
  return grpc::SslServerCredentials(options);
}

ServiceLimits LimitsOf(const ServerConfig& config) {
  ServiceLimits limits;
  limits.max_sessions = config.max_sessions;
  limits.max_frame_rate_hz = config.max_frame_rate_hz;
  limits.session_idle_timeout =
      std::chrono::milliseconds(static_cast<int64_t>(config.session_idle_timeout_s * 1000));
  limits.workers = config.Workers();
  limits.admission.max_busy_fraction = config.admit_busy;
  limits.admission.max_wait_p95_ms = config.admit_wait_ms;
  return limits;
}

MapAdminOptions AdminOptionsOf(const ServerConfig& config) {
  MapAdminOptions options;
  options.max_upload_bytes = static_cast<uint64_t>(config.max_upload_mib) << 20;
  options.read_only = config.maps_read_only;
  return options;
}

MappingLimits MappingLimitsOf(const ServerConfig& config) {
  MappingLimits limits;
  limits.max_jobs = config.max_mapping_jobs;
  limits.threads = config.mapping_threads;
  limits.max_frames = config.max_mapping_frames;
  limits.max_memory_bytes = static_cast<size_t>(config.max_mapping_memory_mib) << 20;
  limits.read_only = config.maps_read_only;
  limits.resume_window_s = config.mapping_resume_s;
  limits.spool_dir =
      config.mapping_spool.empty() ? config.maps_dir + "/.mapping-jobs" : config.mapping_spool;
  limits.min_free_disk_bytes = config.mapping_min_free_mib << 20;
  return limits;
}

// The config checked before anything is built from it.
const ServerConfig& Checked(const ServerConfig& config) {
  config.Check();
  return config;
}

}  // namespace

void ServerConfig::Check() const {
  CheckLinkConfig(*this);
  if (map_memory_mib < 0 || map_memory_mib > (int64_t{1} << 24)) {
    throw UsageError("--map-memory-mib must be 0 (no bound) to 16777216");
  }
  if (max_sessions < 1) throw UsageError("--max-sessions must be at least 1");
  AdmissionOptions admission;
  admission.max_busy_fraction = admit_busy;
  admission.max_wait_p95_ms = admit_wait_ms;
  admission.Check();
  for (const std::string& address : {listen, http}) {
    if (!address.empty() && !IsLoopback(address) && tokens.empty() && !allow_remote) {
      throw UsageError("without --tokens the server listens on loopback only (got " + address +
                       "; --allow-remote overrides)");
    }
  }
  if (threads < 0) throw UsageError("--threads must not be negative");
  if (!(max_frame_rate_hz >= 0)) throw UsageError("--max-frame-rate-hz must not be negative");
  if (max_upload_mib < 1) throw UsageError("--max-upload-mib must be at least 1");
  if (max_mapping_jobs < 0 || max_mapping_jobs > 64) {
    throw UsageError("--max-mapping-jobs must be 0 (no mapping over the link) to 64");
  }
  if (mapping_threads < 1 || mapping_threads > 64) {
    throw UsageError("--mapping-threads must be 1 to 64");
  }
  if (max_mapping_frames < 1) throw UsageError("--max-mapping-frames must be at least 1");
  if (max_mapping_memory_mib < 1 || max_mapping_memory_mib > (int64_t{1} << 24)) {
    throw UsageError("--max-mapping-memory-mib must be 1 to 16777216");
  }
  if (mapping_min_free_mib < 0 || mapping_min_free_mib > (int64_t{1} << 30)) {
    throw UsageError("--mapping-min-free-mib must be 0 to 1073741824");
  }
  if (!(mapping_resume_s >= 0 && mapping_resume_s <= 3600)) {
    throw UsageError("--mapping-resume-s must be 0 to 3600");
  }
  if (tls_cert.empty() != tls_key.empty()) throw UsageError("--tls-cert and --tls-key go together");
  if (!tls_client_ca.empty() && tls_cert.empty()) {
    throw UsageError("--tls-client-ca needs --tls-cert and --tls-key");
  }
}

int ServerConfig::Workers() const {
  // The per-frame engine work runs on at most this many threads at once: the machine's cores.
  return threads > 0 ? threads
                     : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

// A localizability grid a request may ask for: 250,000 cells times headings (3.3 MB on the wire),
// e.g. 125 x 125 m in 0.5 m cells with 16 headings.
constexpr int kMaxLocalizabilityPoses = 250'000;

Server::Server(const ServerConfig& config)
    : config_(Checked(config)),
      auth_(config.tokens.empty() ? TokenAuth() : TokenAuth::FromFile(config.tokens)),
      maps_(config.maps_dir, std::chrono::seconds(config.idle_unload_s),
            static_cast<size_t>(config.map_memory_mib) << 20),
      // One thread: a grid is an operator's question, and the robots' frames come first.
      localizability_(&maps_, kMaxLocalizabilityPoses, /*threads=*/1),
      localization_(&maps_, LimitsOf(config), &auth_),
      admin_(&maps_, &localizability_, AdminOptionsOf(config), &auth_),
      mapping_(&maps_, MappingLimitsOf(config), &auth_),
      fleet_(&localization_.registry(), &auth_, config.max_sessions) {
  const auto credentials = Credentials(config_);
  // A read-only replica must not touch the folder: the temporaries in it may be another
  // server's uploads in progress (whose process ids mean nothing in this one's namespace).
  const int stale = config_.maps_read_only
                        ? 0
                        : mapstore::MapDirectory(config_.maps_dir).RemoveStaleTemporaries();
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort(config_.listen, credentials, &port);
  // gRPC sets SO_REUSEPORT by default: a second server on a port in use would start, and the
  // kernel would share new connections out between the two at random. The address is ours alone.
  builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  // The sync server gives each call a thread, and a Localize stream keeps its thread for its
  // life (mostly waiting on the network); room for every session plus admin calls.
  grpc::ResourceQuota quota("visloc-server");
  quota.SetMaxThreads(config_.max_sessions + config_.max_mapping_jobs + 16);
  builder.SetResourceQuota(quota);
  builder.RegisterService(&localization_);
  builder.RegisterService(&admin_);
  builder.RegisterService(&mapping_);
  builder.RegisterService(&fleet_);
  std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>> counting;
  counting.push_back(rpcs_.InterceptorFactory());
  builder.experimental().SetInterceptorCreators(std::move(counting));
  builder.SetMaxReceiveMessageSize(proto::WireLimits{}.max_message_bytes);
  SetLinkArguments(config_, &builder);
  grpc_server_ = builder.BuildAndStart();
  if (!grpc_server_ || port == 0) {
    throw InputError("cannot listen on " + config_.listen +
                     ": the address is in use (another visloc-server?) or not this machine's");
  }
  grpc::HealthCheckServiceInterface* health = grpc_server_->GetHealthCheckService();
  for (const char* service :
       {"visloc.v1.Localization", "visloc.v1.MapAdmin", "visloc.v1.Mapping", "visloc.v1.Fleet"}) {
    health->SetServingStatus(service, true);
  }
  address_ = config_.listen.substr(0, config_.listen.rfind(':')) + ":" + std::to_string(port);
  if (!config_.http.empty()) {
    HttpSources sources;
    sources.status = [this] { return Status(); };
    sources.readiness = [this] { return Readiness(); };
    sources.maps = [this] { return Maps(); };
    sources.top_view = [this](const std::string& name) { return TopView(name); };
    sources.localizability = [this](const std::string& name) {
      return localizability_.Get(name, LocalizabilityRequest{});
    };
    sources.mapping_jobs = [this] { return mapping_.job_views(); };
    http_ = std::make_unique<HttpEndpoint>(
        HttpOptions{config_.http, config_.tls_cert, config_.tls_key, VislocVersion()},
        std::move(sources), &auth_);
  }
  LogStart(stale);
  janitor_ = std::thread([this] {
    while (!stopping_) {
      std::this_thread::sleep_for(std::chrono::milliseconds(500));
      maps_.UnloadIdle();
      mapping_.ExpireWaitingJobs();
    }
  });
}

Server::~Server() {
  http_.reset();
  fleet_.Stop();
  if (!stopping_) {
    grpc_server_->Shutdown(std::chrono::system_clock::now());
    grpc_server_->Wait();
    stopping_ = true;
  }
  if (janitor_.joinable()) janitor_.join();
}

void Server::LogStart(int stale_temporaries_removed) const {
  Log("server_start",
      {{"listen", address_},
       {"maps", config_.maps_dir},
       {"maps_read_only", config_.maps_read_only ? "yes" : "no"},
       {"max_sessions", std::to_string(config_.max_sessions)},
       {"map_memory_mib",
        config_.map_memory_mib ? std::to_string(config_.map_memory_mib) : "unbounded"},
       {"workers", std::to_string(config_.Workers())},
       {"tls", config_.tls_cert.empty()        ? "off"
               : config_.tls_client_ca.empty() ? "on"
                                               : "mutual"},
       {"max_frame_rate_hz", FormatFixed(config_.max_frame_rate_hz, 1)},
       {"session_idle_timeout_s", FormatFixed(config_.session_idle_timeout_s, 1)},
       {"keepalive_min_ping_interval_s", FormatFixed(config_.keepalive_min_ping_interval_s, 1)},
       {"tokens", auth_.enabled() ? "on" : "off"},
       {"http", http_ ? http_->address() : "off"},
       {"stale_temporaries_removed", std::to_string(stale_temporaries_removed)}});
}

ServerStatus Server::Status() const {
  ServerStatus status;
  status.sessions = localization_.sessions();
  status.counters = localization_.registry().Counters();
  status.rpcs = rpcs_.Snapshot();
  status.max_sessions = config_.max_sessions;
  status.idle_sessions_closed = localization_.idle_sessions_closed();
  status.maps = maps_.LoadedMaps();
  const MapCacheStats cache = maps_.stats();
  status.map_loads = cache.loads;
  status.map_paged_loads = cache.paged_loads;
  status.map_cache_hits = cache.hits;
  status.map_unloads = cache.unloads;
  status.map_load_failures = cache.load_failures;
  status.workers = localization_.workers().permits();
  status.workers_busy = localization_.workers().in_use();
  status.workers_peak = localization_.workers().peak_in_use();
  status.worker_load = localization_.workers().load().Over(WorkerLoad::Clock::now());
  status.admit_busy_fraction = localization_.admission_options().max_busy_fraction;
  status.projected_busy_fraction = localization_.Admission().projected_busy_fraction;
  status.sessions_refused_at_capacity = localization_.sessions_refused_at_capacity();
  return status;
}

std::vector<MapSummary> Server::Maps() const {
  namespace fs = std::filesystem;
  std::vector<MapSummary> maps;
  std::error_code error;
  std::lock_guard<std::mutex> lock(described_mutex_);
  for (const fs::directory_entry& file : fs::directory_iterator(config_.maps_dir, error)) {
    const std::string name = file.path().stem().string();
    if (file.path().extension() != ".db" || !mapstore::IsValidMapName(name)) continue;
    const uint64_t bytes = file.file_size(error);
    const auto modified = file.last_write_time(error);
    DescribedMap& described = described_[name];
    if (described.summary.name.empty() || described.bytes != bytes ||
        described.modified != modified) {
      const mapstore::MapDirectory::Entry entry = maps_.directory().Describe(name);
      described = {bytes, modified, {name, bytes, 0, 0, RedactForClient(entry.error)}};
      if (entry.info) {
        described.summary.keyframes = static_cast<int64_t>(entry.info->keyframes);
        described.summary.points = static_cast<int64_t>(entry.info->points);
      }
    }
    maps.push_back(described.summary);
  }
  std::sort(maps.begin(), maps.end(),
            [](const MapSummary& a, const MapSummary& b) { return a.name < b.name; });
  return maps;
}

MapTopView Server::TopView(const std::string& name, size_t max_points, size_t max_keyframes) {
  const std::shared_ptr<const LocalizationMap> loaded = maps_.Acquire(name);
  const Map& map = loaded->map();
  MapTopView view;
  view.name = name;
  view.total_keyframes = static_cast<int64_t>(map.keyframes.size());
  view.total_points = static_cast<int64_t>(map.points.size());
  // From above: the level frame's x-y, else the map's x-z (the first camera's ground plane).
  Eigen::Matrix<double, 2, 3> plane;
  plane << 1, 0, 0, 0, 0, 1;
  if (const auto frame = mapping::PlanFrameOf(map)) {
    view.frame = frame->name;
    view.frame_how = frame->how;
    view.site_from_map = frame->site_from_map;
    plane = frame->site_from_map.rotation.toRotationMatrix().topRows<2>();
  }
  const Eigen::Vector2d offset = view.frame == "map"
                                     ? Eigen::Vector2d::Zero().eval()
                                     : Eigen::Vector2d(view.site_from_map.translation.head<2>());
  const auto top = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector2d xy = plane * p + offset;
    return std::make_pair(static_cast<float>(xy.x()), static_cast<float>(xy.y()));
  };
  const size_t keyframe_step = map.keyframes.size() / std::max<size_t>(1, max_keyframes) + 1;
  for (size_t k = 0; k < map.keyframes.size(); k += keyframe_step) {
    view.keyframes.push_back(top(map.keyframes[k].map_from_cam.translation));
  }
  const size_t point_step = map.points.size() / std::max<size_t>(1, max_points) + 1;
  for (size_t p = 0; p < map.points.size(); p += point_step) {
    view.points.push_back(top(map.points[p].position_in_map));
  }
  return view;
}

std::string Server::Readiness() const {
  if (draining_) return "draining: the server is shutting down";
  std::error_code error;
  std::filesystem::directory_iterator maps(config_.maps_dir, error);
  if (error) return "the maps folder cannot be read";
  return "";
}

void Server::Drain() {
  draining_ = true;  // /readyz answers 503 from now.
  grpc_server_->GetHealthCheckService()->SetServingStatus(false);
  fleet_.Stop();  // Watches end now; robots' streams get the drain period.
  grpc_server_->Shutdown(std::chrono::system_clock::now() +
                         std::chrono::milliseconds(static_cast<int64_t>(config_.drain_s * 1000)));
  grpc_server_->Wait();
  stopping_ = true;
  if (janitor_.joinable()) janitor_.join();
  http_.reset();
  Log("server_stop", {{"maps_loaded", std::to_string(maps_.stats().loads)}});
}

}  // namespace visloc::server
