#include "server/http/http_endpoint.h"

#include <httplib.h>

#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/thread_priority.h"
#include "server/client_errors.h"
#include "server/http/metrics.h"
#include "server/http/operator_api.h"
#include "server/http/operator_page.h"

namespace visloc::server {
namespace {

// How far below the localization workers the HTTP threads run (nice levels). At +10 a thread
// gets about a tenth of a core that a worker also wants: what the page asks of a large map (its
// view, its localizability grid: seconds of a core for 10,000 keyframes) and every scrape wait
// for the robots' frames, not the other way round.
constexpr int kHttpNiceIncrement = 10;

// httplib's pool, its threads lowered before their first request.
class BackgroundPool : public httplib::TaskQueue {
 public:
  BackgroundPool() : pool_(CPPHTTPLIB_THREAD_POOL_COUNT) {}
  void enqueue(std::function<void()> fn) override {
    pool_.enqueue([fn = std::move(fn)] {
      thread_local bool lowered = false;
      if (!lowered) {
        LowerThisThreadsPriority(kHttpNiceIncrement);
        lowered = true;
      }
      fn();
    });
  }
  void shutdown() override { pool_.shutdown(); }

 private:
  httplib::ThreadPool pool_;
};

// The client's Accept-Encoding without Brotli ("br"), so that httplib answers it with gzip.
// Debian's cpp-httplib (0.11) prefers Brotli whenever a client accepts it, at Brotli's slowest
// quality (11): a small map's view took 0.37 s of a core (gzip: 0.02 s) and a 10,000-keyframe
// one 1.4 s, for 8% fewer bytes than gzip (41,003 against 44,806). Every browser accepts Brotli.
void RefuseBrotli(const httplib::Request& request) {
  // httplib hands the pre-routing handler its own (non-const) request, before it chooses the
  // response's encoding; this is the only place the choice can be steered.
  httplib::Headers& headers = const_cast<httplib::Request&>(request).headers;
  const auto accepted = headers.find("Accept-Encoding");
  if (accepted == headers.end()) return;
  std::string kept;
  for (const std::string& coding : Split(accepted->second, ',')) {  // "gzip", "br;q=1.0"...
    if (Trim(std::string_view(coding).substr(0, coding.find(';'))) == "br") continue;
    kept += (kept.empty() ? "" : ", ") + coding;
  }
  accepted->second = kept;
}

std::unique_ptr<httplib::Server> MakeServer(const HttpOptions& options) {
  std::unique_ptr<httplib::Server> server;
  if (options.tls_cert.empty()) {
    server = std::make_unique<httplib::Server>();
  } else {
    auto tls =
        std::make_unique<httplib::SSLServer>(options.tls_cert.c_str(), options.tls_key.c_str());
    if (!tls->is_valid()) throw InputError("the HTTP endpoint cannot use the TLS certificate");
    server = std::move(tls);
  }
  server->new_task_queue = [] { return new BackgroundPool(); };
  server->set_pre_routing_handler([](const httplib::Request& request, httplib::Response&) {
    RefuseBrotli(request);
    return httplib::Server::HandlerResponse::Unhandled;
  });
  return server;
}

// The caller's "Authorization" header, checked for any role (reading is what every token may).
AuthDecision Authorize(const TokenAuth& auth, const httplib::Request& request) {
  if (!request.has_header("Authorization")) return auth.Authorize(std::nullopt, Role::kLocalize);
  const std::string value = request.get_header_value("Authorization");
  return auth.Authorize(std::string_view(value), Role::kLocalize);
}

// Whether the call may read; if not, the refusal is written into `response` (401 or 403).
bool Allowed(const TokenAuth& auth, const httplib::Request& request, httplib::Response* response) {
  const AuthDecision decision = Authorize(auth, request);
  if (decision.allowed()) return true;
  response->status = decision.outcome == AuthDecision::Outcome::kUnauthenticated ? 401 : 403;
  if (response->status == 401) response->set_header("WWW-Authenticate", "Bearer");
  response->set_content(decision.message + "\n", "text/plain");
  return false;
}

// A map's JSON (its view, its localizability): 404 for an unknown map, 422 for one that does not
// load or cannot answer (the reason, redacted as gRPC errors are).
void AnswerMapJson(httplib::Response* response, const std::function<std::string()>& json) {
  try {
    response->set_content(json(), "application/json");
  } catch (const NotFoundError& e) {
    response->status = 404;
    response->set_content(RedactForClient(e.what()) + "\n", "text/plain");
  } catch (const InputError& e) {
    response->status = 422;
    response->set_content(RedactForClient(e.what()) + "\n", "text/plain");
  }
}

}  // namespace

HttpEndpoint::HttpEndpoint(const HttpOptions& options, HttpSources sources, const TokenAuth* auth)
    : sources_(std::move(sources)), auth_(auth), http_(MakeServer(options)) {
  const size_t colon = options.listen.rfind(':');
  const auto port =
      colon == std::string::npos ? std::nullopt : ParseInt64(options.listen.substr(colon + 1));
  if (!port || *port < 0 || *port > 65535) {
    throw UsageError("--http needs HOST:PORT, got '" + options.listen + "'");
  }
  std::string host = options.listen.substr(0, colon);
  if (host.size() > 2 && host.front() == '[' && host.back() == ']')
    host = host.substr(1, host.size() - 2);
  Route(options);
  RouteOperatorPage();
  const int bound =
      *port == 0
          ? http_->bind_to_any_port(host)
          : (http_->bind_to_port(host, static_cast<int>(*port)) ? static_cast<int>(*port) : -1);
  if (bound <= 0) {
    throw InputError("cannot listen on " + options.listen +
                     " for HTTP: the address is in use or not this machine's");
  }
  address_ = options.listen.substr(0, colon) + ":" + std::to_string(bound);
  thread_ = std::thread([this] { http_->listen_after_bind(); });
}

HttpEndpoint::~HttpEndpoint() {
  stopping_ = true;  // Event streams end at their next event.
  http_->stop();
  if (thread_.joinable()) thread_.join();
}

void HttpEndpoint::Route(const HttpOptions& options) {
  http_->Get("/healthz", [](const httplib::Request&, httplib::Response& response) {
    response.set_content("ok\n", "text/plain");
  });
  http_->Get("/readyz", [this](const httplib::Request&, httplib::Response& response) {
    const std::string why_not = sources_.readiness();
    response.status = why_not.empty() ? 200 : 503;
    response.set_content(why_not.empty() ? "ready\n" : why_not + "\n", "text/plain");
  });
  const std::string version = options.version;
  http_->Get("/metrics",
             [this, version](const httplib::Request& request, httplib::Response& response) {
               if (!Allowed(*auth_, request, &response)) return;
               response.set_content(PrometheusText(sources_.status(), version),
                                    "text/plain; version=0.0.4; charset=utf-8");
             });
}

void HttpEndpoint::RouteOperatorPage() {
  http_->Get("/", [](const httplib::Request&, httplib::Response& response) {
    response.set_content(OperatorPageHtml(), "text/html; charset=utf-8");
  });
  http_->Get("/api/sessions", [this](const httplib::Request& request, httplib::Response& response) {
    if (!Allowed(*auth_, request, &response)) return;
    const ServerStatus status = sources_.status();
    response.set_content(SessionsJson(status, std::chrono::system_clock::now()),
                         "application/json");
  });
  http_->Get("/api/mapping", [this](const httplib::Request& request, httplib::Response& response) {
    if (!Allowed(*auth_, request, &response)) return;
    response.set_content(MappingJobsJson(sources_.mapping_jobs ? sources_.mapping_jobs()
                                                               : std::vector<MappingJobView>{}),
                         "application/json");
  });
  http_->Get("/api/maps", [this](const httplib::Request& request, httplib::Response& response) {
    if (!Allowed(*auth_, request, &response)) return;
    response.set_content(MapsJson(sources_.maps()), "application/json");
  });
  http_->Get(R"(/api/maps/([A-Za-z0-9_.-]+)/view)", [this](const httplib::Request& request,
                                                           httplib::Response& response) {
    if (!Allowed(*auth_, request, &response)) return;
    AnswerMapJson(&response, [&] { return TopViewJson(sources_.top_view(request.matches[1])); });
  });
  http_->Get(R"(/api/maps/([A-Za-z0-9_.-]+)/localizability)",
             [this](const httplib::Request& request, httplib::Response& response) {
               if (!Allowed(*auth_, request, &response)) return;
               // A map whose grid cannot be computed (no level frame, too large) is an answer
               // the page shows, not a failed request.
               AnswerMapJson(&response, [&] {
                 const std::string name = request.matches[1];
                 try {
                   return LocalizabilityJson(*sources_.localizability(name));
                 } catch (const NotFoundError&) {
                   throw;
                 } catch (const InputError& e) {
                   return LocalizabilityProblemJson(name, RedactForClient(e.what()));
                 }
               });
             });
  http_->Get("/api/events", [this](const httplib::Request& request, httplib::Response& response) {
    if (!Allowed(*auth_, request, &response)) return;
    if (++event_streams_ > kMaxEventStreams) {
      --event_streams_;
      response.status = 503;
      response.set_content("too many pages open on this server\n", "text/plain");
      return;
    }
    response.set_header("Cache-Control", "no-cache");
    response.set_chunked_content_provider(
        "text/event-stream",
        [this](size_t, httplib::DataSink& sink) {
          if (stopping_) return false;
          const ServerStatus status = sources_.status();
          const std::string event =
              "data: " + SessionsJson(status, std::chrono::system_clock::now()) + "\n\n";
          if (!sink.write(event.data(), event.size())) return false;
          std::this_thread::sleep_for(std::chrono::milliseconds(kEventIntervalMs));
          return !stopping_.load();
        },
        [this](bool) { --event_streams_; });
  });
}

}  // namespace visloc::server
