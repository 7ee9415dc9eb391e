#pragma once
// A bad network link for tests, on loopback: a TCP proxy between a client and a server that
// adds latency and jitter, caps bandwidth, stalls (forwards and accepts nothing for a while,
// connections kept) and cuts (closes every connection and refuses new ones for a while). This
// machine's kernel has no netem; this is the WiFi a robot sees, in user space.
//
// Every delay is bounded: a stall or cut ends by itself, and the destructor closes everything.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <list>
#include <memory>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

namespace visloc::testing {

struct LinkProfile {
  double latency_ms = 0.0;  // One way, each direction.
  double jitter_ms = 0.0;   // Uniform in [0, jitter_ms) added to each chunk (order kept).
  double bandwidth_mbit_s = 0.0;  // Each direction; 0: unlimited.
};

class LinkProxy {
 public:
  // Listens on 127.0.0.1 (a free port) and forwards to `upstream` ("127.0.0.1:PORT").
  LinkProxy(const std::string& upstream, const LinkProfile& profile);
  ~LinkProxy();
  LinkProxy(const LinkProxy&) = delete;
  LinkProxy& operator=(const LinkProxy&) = delete;

  std::string address() const { return "127.0.0.1:" + std::to_string(port_); }
  void SetProfile(const LinkProfile& profile);
  // Nothing is forwarded or accepted for `duration`; open connections stay open.
  void Stall(std::chrono::milliseconds duration);
  // Every open connection is closed now, and new ones are refused for `duration`.
  void Cut(std::chrono::milliseconds duration);
  // Connections accepted so far.
  int connections() const { return connections_.load(); }

 private:
  struct Chunk {
    std::chrono::steady_clock::time_point release;
    std::string bytes;
  };
  // One direction of one connection: a reader thread queues chunks with their release times,
  // a writer thread sends them when due.
  struct Pipe {
    int from = -1, to = -1;
    std::mutex mutex;
    std::condition_variable ready;
    std::deque<Chunk> chunks;
    std::chrono::steady_clock::time_point last_release{};
    bool done = false;
    std::thread reader, writer;
  };
  struct Connection {
    int client = -1, server = -1;
    Pipe up, down;
  };

  void Accept();
  void StartPipe(Pipe* pipe, int from, int to);
  void ReadPipe(Pipe* pipe);
  void WritePipe(Pipe* pipe);
  bool Stalled() const;
  bool CutActive() const;
  void CloseConnection(Connection* connection);

  std::string upstream_host_;
  int upstream_port_ = 0;
  int listener_ = -1;
  int port_ = 0;
  mutable std::mutex mutex_;
  LinkProfile profile_;
  std::mt19937 rng_{7};
  std::chrono::steady_clock::time_point stall_until_{}, cut_until_{};
  std::list<std::unique_ptr<Connection>> open_;
  std::atomic<bool> stopping_{false};
  std::atomic<int> connections_{0};
  std::thread acceptor_;
};

}  // namespace visloc::testing
