#include "tests/support/link_proxy.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <stdexcept>

namespace visloc::testing {
namespace {

using Clock = std::chrono::steady_clock;

int ConnectTo(const std::string& host, int port) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<uint16_t>(port));
  inet_pton(AF_INET, host.c_str(), &address.sin_addr);
  if (connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)) != 0) {
    close(fd);
    return -1;
  }
  const int one = 1;
  setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
  return fd;
}

// Waits up to `ms` for `fd` to be readable; false on timeout.
bool Readable(int fd, int ms) {
  pollfd p{fd, POLLIN, 0};
  return poll(&p, 1, ms) > 0;
}

}  // namespace

LinkProxy::LinkProxy(const std::string& upstream, const LinkProfile& profile)
    : profile_(profile) {
  const size_t colon = upstream.rfind(':');
  upstream_host_ = upstream.substr(0, colon);
  upstream_port_ = std::stoi(upstream.substr(colon + 1));
  listener_ = socket(AF_INET, SOCK_STREAM, 0);
  const int one = 1;
  setsockopt(listener_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (bind(listener_, reinterpret_cast<sockaddr*>(&address), sizeof(address)) != 0 ||
      listen(listener_, 64) != 0) {
    throw std::runtime_error("LinkProxy: cannot listen on loopback");
  }
  socklen_t length = sizeof(address);
  getsockname(listener_, reinterpret_cast<sockaddr*>(&address), &length);
  port_ = ntohs(address.sin_port);
  acceptor_ = std::thread([this] { Accept(); });
}

LinkProxy::~LinkProxy() {
  stopping_ = true;
  acceptor_.join();
  close(listener_);
  // Closed outside the lock: the pipes' readers take it to read the profile.
  std::list<std::unique_ptr<Connection>> open;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    open.swap(open_);
  }
  for (auto& connection : open) CloseConnection(connection.get());
}

void LinkProxy::SetProfile(const LinkProfile& profile) {
  std::lock_guard<std::mutex> lock(mutex_);
  profile_ = profile;
}

void LinkProxy::Stall(std::chrono::milliseconds duration) {
  std::lock_guard<std::mutex> lock(mutex_);
  stall_until_ = Clock::now() + duration;
}

void LinkProxy::Cut(std::chrono::milliseconds duration) {
  std::list<std::unique_ptr<Connection>> cut;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    cut_until_ = Clock::now() + duration;
    cut.swap(open_);
  }
  for (auto& connection : cut) CloseConnection(connection.get());
}

bool LinkProxy::Stalled() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return Clock::now() < stall_until_;
}

bool LinkProxy::CutActive() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return Clock::now() < cut_until_;
}

void LinkProxy::CloseConnection(Connection* c) {
  for (Pipe* pipe : {&c->up, &c->down}) {
    {
      std::lock_guard<std::mutex> lock(pipe->mutex);
      pipe->done = true;
    }
    pipe->ready.notify_all();
  }
  // An abortive close (RST), as when an access point goes away: both ends see the reset.
  const linger abort{1, 0};
  for (int fd : {c->client, c->server}) {
    setsockopt(fd, SOL_SOCKET, SO_LINGER, &abort, sizeof(abort));
    shutdown(fd, SHUT_RDWR);
  }
  for (Pipe* pipe : {&c->up, &c->down}) {
    if (pipe->reader.joinable()) pipe->reader.join();
    if (pipe->writer.joinable()) pipe->writer.join();
  }
  close(c->client);
  close(c->server);
}

void LinkProxy::Accept() {
  while (!stopping_) {
    // While stalled nothing is accepted: new connections wait in the backlog.
    if (Stalled() || !Readable(listener_, 20)) {
      if (Stalled()) std::this_thread::sleep_for(std::chrono::milliseconds(10));
      continue;
    }
    const int client = accept(listener_, nullptr, nullptr);
    if (client < 0) continue;
    if (CutActive()) {  // The link is down: the connection dies at once.
      const linger abort{1, 0};
      setsockopt(client, SOL_SOCKET, SO_LINGER, &abort, sizeof(abort));
      close(client);
      continue;
    }
    const int server = ConnectTo(upstream_host_, upstream_port_);
    if (server < 0) {
      close(client);
      continue;
    }
    const int one = 1;
    setsockopt(client, IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
    auto connection = std::make_unique<Connection>();
    connection->client = client;
    connection->server = server;
    StartPipe(&connection->up, client, server);
    StartPipe(&connection->down, server, client);
    ++connections_;
    std::lock_guard<std::mutex> lock(mutex_);
    open_.push_back(std::move(connection));
  }
}

void LinkProxy::StartPipe(Pipe* pipe, int from, int to) {
  pipe->from = from;
  pipe->to = to;
  pipe->reader = std::thread([this, pipe] { ReadPipe(pipe); });
  pipe->writer = std::thread([this, pipe] { WritePipe(pipe); });
}

// Each chunk read is released after the latency (plus jitter) and after the previous chunk has
// had its time on a link of the given bandwidth; release times never go backwards (TCP order).
void LinkProxy::ReadPipe(Pipe* pipe) {
  char buffer[16384];
  while (true) {
    {
      std::lock_guard<std::mutex> lock(pipe->mutex);
      if (pipe->done) return;
    }
    if (!Readable(pipe->from, 20)) continue;
    const ssize_t n = recv(pipe->from, buffer, sizeof(buffer), 0);
    Clock::time_point release;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      const double jitter =
          profile_.jitter_ms > 0
              ? std::uniform_real_distribution<double>(0.0, profile_.jitter_ms)(rng_)
              : 0.0;
      release = Clock::now() + std::chrono::microseconds(static_cast<int64_t>(
                                   (profile_.latency_ms + jitter) * 1000));
      if (profile_.bandwidth_mbit_s > 0 && n > 0) {
        const auto on_wire = std::chrono::microseconds(
            static_cast<int64_t>(n * 8 / profile_.bandwidth_mbit_s));
        release = std::max(release, pipe->last_release + on_wire);
      }
    }
    std::lock_guard<std::mutex> lock(pipe->mutex);
    release = std::max(release, pipe->last_release);
    pipe->last_release = release;
    if (n <= 0) {  // The sender closed: pass the close on after what is queued.
      pipe->chunks.push_back({release, std::string()});
      pipe->ready.notify_all();
      return;
    }
    pipe->chunks.push_back({release, std::string(buffer, static_cast<size_t>(n))});
    pipe->ready.notify_all();
  }
}

void LinkProxy::WritePipe(Pipe* pipe) {
  while (true) {
    Chunk chunk;
    {
      std::unique_lock<std::mutex> lock(pipe->mutex);
      pipe->ready.wait(lock, [pipe] { return pipe->done || !pipe->chunks.empty(); });
      if (pipe->done) return;
      if (Clock::now() < pipe->chunks.front().release || Stalled()) {
        pipe->ready.wait_for(lock, std::chrono::milliseconds(1));
        continue;
      }
      chunk = std::move(pipe->chunks.front());
      pipe->chunks.pop_front();
    }
    if (chunk.bytes.empty()) {
      shutdown(pipe->to, SHUT_WR);
      return;
    }
    size_t sent = 0;
    while (sent < chunk.bytes.size()) {
      const ssize_t n = send(pipe->to, chunk.bytes.data() + sent, chunk.bytes.size() - sent,
                             MSG_NOSIGNAL);
      if (n <= 0) return;
      sent += static_cast<size_t>(n);
    }
  }
}

}  // namespace visloc::testing
