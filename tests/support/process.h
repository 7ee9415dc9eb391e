#pragma once
// Runs a program as a child process and captures what it prints, for end-to-end tests that
// exercise the real binaries.

#include <functional>
#include <string>
#include <vector>

namespace visloc::testing {

struct ProcessResult {
  int exit_code = -1;  // The exit status, or 128 + signal number when killed by a signal.
  std::string out;     // Everything written to stdout.
  std::string err;     // Everything written to stderr.
};

// Runs `argv[0]` with the arguments (no shell involved) and waits for it; stdin is /dev/null.
ProcessResult RunProcess(const std::vector<std::string>& argv);

// Starts `argv[0]` with the arguments without waiting; its output goes to /dev/null.
// Returns the child's process id.
int SpawnProcess(const std::vector<std::string>& argv);
// The same with stdout and stderr written to the given files.
int SpawnProcess(const std::vector<std::string>& argv, const std::string& out_path,
                 const std::string& err_path);
// Sends `signal` to the child and reaps it. Returns the exit code as RunProcess reports it.
int KillProcess(int pid, int signal);
// Waits for the child to end. Returns the exit code as RunProcess reports it.
int WaitProcess(int pid);
// Polls `ready` every 20 ms until it holds or `timeout_ms` passed; whether it held. For tests
// that wait on what another process does, never on a fixed sleep.
bool WaitUntil(const std::function<bool()>& ready, int timeout_ms = 10000);

// How many times `needle` occurs in `text`, overlapping occurrences included (a log's events).
size_t CountOccurrences(const std::string& text, const std::string& needle);

// A real visloc-server on a free loopback port, for end-to-end tests: started in the
// constructor (waits until it prints "listening on ADDRESS"), SIGTERMed in the destructor.
// $VISLOC_TEST_SERVER, when set, names the server binary to run instead.
class ServerProcess {
 public:
  ServerProcess(const std::string& server_binary, const std::string& maps_dir,
                std::vector<std::string> extra_args = {});
  ~ServerProcess();
  ServerProcess(const ServerProcess&) = delete;
  ServerProcess& operator=(const ServerProcess&) = delete;

  const std::string& address() const { return address_; }
  int pid() const { return pid_; }
  // What the server logged to stderr so far.
  std::string Log() const;
  // Waits (polling, at most `timeout_ms`) until the log holds `text`; whether it came.
  bool WaitForLog(const std::string& text, int timeout_ms = 10000) const;
  // Sends `signal` (SIGTERM: a drain; SIGKILL: a crash) and waits; returns the exit code.
  // Idempotent.
  int Stop(int signal = 15);

 private:
  std::string dir_;
  std::string address_;
  int pid_ = -1;
  int exit_code_ = -1;
};

}  // namespace visloc::testing
