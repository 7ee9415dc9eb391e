#pragma once
// Runs a program as a child process and captures what it prints, for end-to-end tests that
// exercise the real binaries.

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
// Sends `signal` to the child and reaps it. Returns the exit code as RunProcess reports it.
int KillProcess(int pid, int signal);
// Waits for the child to end. Returns the exit code as RunProcess reports it.
int WaitProcess(int pid);

}  // namespace visloc::testing
