#include "tests/support/process.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <sstream>

#include "core/util/check.h"
#include "core/util/temp_dir.h"

namespace visloc::testing {
namespace {

std::string ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

int ExitCode(int status) {
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

// Forks and executes argv with stdin from /dev/null and stdout/stderr to the given files.
pid_t Start(const std::vector<std::string>& argv, const std::string& out_path,
            const std::string& err_path) {
  VISLOC_CHECK(!argv.empty(), "no program given");
  std::vector<char*> args;
  for (const std::string& arg : argv) args.push_back(const_cast<char*>(arg.c_str()));
  args.push_back(nullptr);
  const pid_t pid = fork();
  VISLOC_CHECK(pid >= 0, "fork failed");
  if (pid == 0) {
    const int in = open("/dev/null", O_RDONLY);
    const int out = open(out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    const int err = open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    if (in < 0 || out < 0 || err < 0) _exit(126);
    dup2(in, STDIN_FILENO);
    dup2(out, STDOUT_FILENO);
    dup2(err, STDERR_FILENO);
    execv(args[0], args.data());
    _exit(127);
  }
  return pid;
}

}  // namespace

int SpawnProcess(const std::vector<std::string>& argv) {
  return Start(argv, "/dev/null", "/dev/null");
}

int WaitProcess(int pid) {
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
  }
  return ExitCode(status);
}

int KillProcess(int pid, int signal) {
  kill(pid, signal);
  return WaitProcess(pid);
}

ProcessResult RunProcess(const std::vector<std::string>& argv) {
  VISLOC_CHECK(!argv.empty(), "no program given");
  TempDir capture("visloc-proc");
  const std::string out_path = capture.File("stdout"), err_path = capture.File("stderr");
  const int exit_code = WaitProcess(Start(argv, out_path, err_path));
  ProcessResult result;
  result.exit_code = exit_code;
  result.out = ReadAll(out_path);
  result.err = ReadAll(err_path);
  return result;
}

}  // namespace visloc::testing
