#pragma once
// One table-driven dispatcher for `visloc COMMAND` and for verb groups such as `visloc map VERB`:
// usage text, --help and unknown-command errors are produced in one place.

#include <string>
#include <vector>

#include "client/commands.h"

namespace visloc::cli {

struct Subcommand {
  const char* name;
  const char* summary;
  int (*run)(const Args&);
};

// Runs the subcommand named by args[0] with the remaining arguments. With no arguments prints
// the usage to stderr and returns 2; with --help prints it to stdout and returns 0. An unknown
// name throws UsageError. `usage` is e.g. "visloc map VERB [options]".
int DispatchSubcommand(const std::string& usage, const std::string& description,
                       const std::vector<Subcommand>& table, const Args& args);

}  // namespace visloc::cli
