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

}  // namespace visloc::testing
