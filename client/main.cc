// visloc: the command-line client. See ../shared/product.md for the verbs and flags.

#include <unistd.h>
#include <cstdio>
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include "client/commands.h"
#include "core/util/args.h"

namespace visloc::cli {

bool ShowProgress() { return isatty(STDERR_FILENO) == 1; }

namespace {

struct Command {
  const char* name;
  const char* summary;
  int (*run)(const Args&);
};

const Command kCommands[] = {
    {"sim", "render synthetic stereo sequences with exact ground truth", RunSim},
    {"eval", "accuracy of a trajectory against ground truth (ATE, RPE, coverage)", RunEval},
    {"map", "manage map files: info, verify, export, list, delete, rename", RunMap},
};

void PrintUsage(std::ostream& out) {
  out << "usage: visloc COMMAND [options]\n\n"
         "visloc: visual localization for robots. Commands:\n";
  for (const Command& command : kCommands) {
    std::string name = command.name;
    name.resize(12, ' ');
    out << "  " << name << command.summary << "\n";
  }
  out << "\n'visloc COMMAND --help' describes a command's options.\n";
}

}  // namespace
}  // namespace visloc::cli

int main(int argc, char** argv) {
  using namespace visloc::cli;
  if (argc < 2 || std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h") {
    PrintUsage(argc < 2 ? std::cerr : std::cout);
    return argc < 2 ? 2 : 0;
  }
  const std::string verb = argv[1];
  const Args args(argv + 2, argv + argc);
  for (const Command& command : kCommands) {
    if (verb != command.name) continue;
    try {
      return command.run(args);
    } catch (const visloc::UsageError& e) {
      std::cerr << "visloc " << verb << ": " << e.what() << " (see 'visloc " << verb
                << " --help')\n";
      return 2;
    } catch (const std::exception& e) {
      std::cerr << "visloc " << verb << ": " << e.what() << "\n";
      return 1;
    }
  }
  std::cerr << "visloc: unknown command '" << verb << "' (see 'visloc --help')\n";
  return 2;
}
