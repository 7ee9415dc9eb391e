#include "client/subcommands.h"

#include <algorithm>
#include <cstring>
#include <iostream>

#include "core/util/args.h"

namespace visloc::cli {

int DispatchSubcommand(const std::string& usage, const std::string& description,
                       const std::vector<Subcommand>& table, const Args& args) {
  if (args.empty() || args[0] == "--help" || args[0] == "-h") {
    std::ostream& out = args.empty() ? std::cerr : std::cout;
    out << "usage: " << usage << "\n\n" << description << "\n";
    // The summaries in one column, at least two spaces after the longest name.
    size_t width = 12;
    for (const Subcommand& command : table) width = std::max(width, std::strlen(command.name) + 2);
    for (const Subcommand& command : table) {
      std::string name = command.name;
      name.resize(width, ' ');
      out << "  " << name << command.summary << "\n";
    }
    out << "\n'" << usage.substr(0, usage.find(" [")) << " --help' describes its options.\n";
    return args.empty() ? 2 : 0;
  }
  for (const Subcommand& command : table) {
    if (args[0] == command.name) return command.run(Args(args.begin() + 1, args.end()));
  }
  throw UsageError("unknown command '" + args[0] + "'");
}

}  // namespace visloc::cli
