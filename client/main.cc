// visloc: the command-line client. See ../shared/product.md for the verbs and flags.

#include <unistd.h>

#include <algorithm>
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include "client/commands.h"
#include "client/subcommands.h"
#include "core/features/features.h"
#include "core/util/args.h"
#include "core/util/json.h"
#include "core/util/memory.h"
#include "core/util/version.h"

namespace visloc::cli {

bool ShowProgress() { return isatty(STDERR_FILENO) == 1; }

namespace {

const std::vector<Subcommand> kCommands = {
    {"sim", "render synthetic stereo sequences with exact ground truth", RunSim},
    {"eval", "accuracy of a trajectory against ground truth (ATE, RPE, coverage)", RunEval},
    {"calibrate", "calibrate a camera or a stereo pair from chessboard images", RunCalibrate},
    {"dataset", "inspect and prepare datasets: check, import, groundtruth", RunDataset},
    {"map",
     "build and manage maps: build, info, verify, export, merge, extend, update, align, "
     "localizability, list, delete, rename, upload, download",
     RunMap},
    {"localize", "localize a dataset's images in a map, in-process (no server)", RunLocalize},
    {"stream", "stream a dataset to visloc-server as one robot session", RunStream},
    {"relocalize", "ask visloc-server where one image was taken", RunRelocalize},
    {"plot", "top view of a map and a trajectory (PNG or SVG)", RunPlot},
    {"bench", "time the engine, its baselines and a reference on a dataset", RunBench},
    {"health", "ask visloc-server whether it is serving (grpc.health.v1)", RunHealth},
    {"sessions", "the live robots of a visloc-server: map, status, pose, inliers, latency",
     RunSessions},
    {"jobs", "the mapping jobs of a visloc-server: maps being built from streamed stereo runs",
     RunJobs},
    {"load", "how many robots a visloc-server answers in time (many robots from one process)",
     RunLoad},
};

// A failed command says why on stderr ("visloc VERB: reason"). Asked for --json, it also prints
// one JSON object on stdout, so a script that reads stdout sees the failure and its reason:
// {"ok":false,"command":"visloc map info","error":"...","exit_code":1}. Returns `exit_code`.
int ReportFailure(const Args& args, const std::string& command, const std::string& message,
                  int exit_code) {
  std::cerr << command << ": " << message << "\n";
  if (std::find(args.begin(), args.end(), "--json") != args.end()) {
    JsonWriter json;
    json.BeginObject()
        .Field("ok", false)
        .Field("command", command)
        .Field("error", message)
        .Field("exit_code", exit_code)
        .EndObject();
    std::cout << json.str() << std::endl;
  }
  return exit_code;
}

}  // namespace
}  // namespace visloc::cli

int main(int argc, char** argv) {
  using namespace visloc::cli;
  visloc::KeepFreedMemoryForReuse();
  visloc::RunOpenCvOnCallingThread();
  const Args args(argv + 1, argv + argc);
  if (args.size() == 1 && args[0] == "--version") {
    std::cout << "visloc " << visloc::VislocVersion() << "\n";
    return 0;
  }
  // Errors are reported as "visloc VERB: reason", naming the command the user ran.
  // With its own verb for the commands that have verbs ("visloc map build"), so that the help
  // an error points to is the one that lists the flag.
  std::string verb;
  for (const Subcommand& command : kCommands) {
    if (!args.empty() && args[0] == command.name) verb = std::string(" ") + command.name;
  }
  if ((verb == " map" || verb == " dataset") && args.size() > 1 && args[1].rfind("--", 0) != 0) {
    verb += " " + args[1];
  }
  try {
    return DispatchSubcommand(
        "visloc COMMAND [options]",
        "visloc: visual localization for robots ('visloc --version' prints its version). "
        "Commands:",
        kCommands, args);
  } catch (const visloc::UsageError& e) {
    const std::string message = std::string(e.what()) + " (see 'visloc" + verb + " --help')";
    return ReportFailure(args, "visloc" + verb, message, 2);
  } catch (const std::exception& e) {
    return ReportFailure(args, "visloc" + verb, e.what(), 1);
  }
}
