#include "tests/support/process.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

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

int SpawnProcess(const std::vector<std::string>& argv, const std::string& out_path,
                 const std::string& err_path) {
  return Start(argv, out_path, err_path);
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

ServerProcess::ServerProcess(const std::string& server_binary, const std::string& maps_dir,
                             std::vector<std::string> extra_args) {
  static int counter = 0;
  dir_ = (std::filesystem::temp_directory_path() /
          ("visloc-server-" + std::to_string(getpid()) + "-" + std::to_string(counter++)))
             .string();
  std::filesystem::create_directories(dir_);
  // $VISLOC_TEST_SERVER swaps in another build of the server (run these tests by hand
  // against the ThreadSanitizer build of visloc-server).
  const char* other_build = std::getenv("VISLOC_TEST_SERVER");
  std::vector<std::string> argv = {other_build ? other_build : server_binary, "--maps", maps_dir,
                                   "--listen", "127.0.0.1:0"};
  argv.insert(argv.end(), extra_args.begin(), extra_args.end());
  // Admission by load is off unless a test asks for it: under a sanitizer the engine runs ten
  // times slower, and a test of something else that starts a robot beside others would be
  // refused for a load that a release build never reaches (fleet_e2e_test tests admission).
  if (std::find(extra_args.begin(), extra_args.end(), "--admit-busy") == extra_args.end()) {
    argv.insert(argv.end(), {"--admit-busy", "0"});
  }
  pid_ = SpawnProcess(argv, dir_ + "/stdout", dir_ + "/stderr");
  const std::string prefix = "listening on ";
  for (int attempt = 0; attempt < 600 && address_.empty(); ++attempt) {
    const std::string out = ReadAll(dir_ + "/stdout");
    const size_t at = out.find(prefix);
    const size_t end = at == std::string::npos ? at : out.find('\n', at);
    if (end != std::string::npos) {
      address_ = out.substr(at + prefix.size(), end - at - prefix.size());
      break;
    }
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      exit_code_ = ExitCode(status);
      pid_ = -1;
      break;
    }
    usleep(50'000);
  }
  VISLOC_CHECK(!address_.empty(), "visloc-server did not start: ", ReadAll(dir_ + "/stderr"));
}

ServerProcess::~ServerProcess() {
  Stop();
  std::error_code ignored;
  std::filesystem::remove_all(dir_, ignored);
}

std::string ServerProcess::Log() const { return ReadAll(dir_ + "/stderr"); }

bool WaitUntil(const std::function<bool()>& ready, int timeout_ms) {
  for (int waited_ms = 0; !ready(); waited_ms += 20) {
    if (waited_ms >= timeout_ms) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

size_t CountOccurrences(const std::string& text, const std::string& needle) {
  size_t count = 0;
  for (size_t at = text.find(needle); at != std::string::npos; at = text.find(needle, at + 1)) {
    ++count;
  }
  return count;
}

bool ServerProcess::WaitForLog(const std::string& text, int timeout_ms) const {
  return WaitUntil([&] { return Log().find(text) != std::string::npos; }, timeout_ms);
}

int ServerProcess::Stop(int signal) {
  if (pid_ > 0) {
    exit_code_ = KillProcess(pid_, signal);
    pid_ = -1;
  }
  return exit_code_;
}

}  // namespace visloc::testing
