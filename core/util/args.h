#pragma once
// A small command-line parser for the `visloc` subcommands and `visloc-server`: flags are
// declared with their target variable and help text, so `--help` is generated and every
// parse error names the offending flag.

#include <cstdint>
#include <optional>
#include <ostream>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

namespace visloc {

// Thrown for malformed command lines; the CLI prints it with a pointer to --help.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Options filled from flags, checked by their own Check(): what it throws (CheckError, or
// std::invalid_argument from the client library, both logic errors) becomes a UsageError, so a
// bad flag value exits 2 with the options' own words.
template <typename Options>
void CheckFlags(const Options& options) {
  try {
    options.Check();
  } catch (const std::logic_error& e) {
    throw UsageError(e.what());
  }
}

class ArgParser {
 public:
  // `command` is e.g. "visloc eval"; `summary` is the one-line description shown by --help.
  ArgParser(std::string command, std::string summary);

  // Flags take a value ("--out DIR" or "--out=DIR"); the target keeps its default when absent.
  void AddFlag(const std::string& name, std::string* target, const std::string& help,
               bool required = false);
  // A required flag shows no default: its value before parsing means nothing.
  void AddFlag(const std::string& name, int* target, const std::string& help,
               bool required = false);
  void AddFlag(const std::string& name, int64_t* target, const std::string& help,
               bool required = false);
  void AddFlag(const std::string& name, double* target, const std::string& help,
               bool required = false);
  // The default --help shows for flag `name` when its variable's initial value stands for
  // something else (0: "computed from ..."); empty shows none.
  void SetDefaultText(const std::string& name, const std::string& text);
  // A list flag: one or more values up to the next "--" argument ("--left a.png b.png"), or
  // given again ("--left a.png --left b.png"); values append.
  void AddList(const std::string& name, std::vector<std::string>* target, const std::string& help,
               bool required = false);
  // A switch: present means true ("--json").
  void AddSwitch(const std::string& name, bool* target, const std::string& help);
  // Positional arguments are filled in declaration order.
  void AddPositional(const std::string& name, std::string* target, const std::string& help,
                     bool required = true);

  // `former` is accepted for the flag `name` (declared before), which it was called once, so
  // scripts written for it keep working; --help shows only the current name.
  void AddFormerName(const std::string& former, const std::string& name);

  // Parses `args` (without the program and subcommand names). Returns false when --help was
  // given, after writing the help text to `help_out`. Throws UsageError on bad input.
  bool Parse(const std::vector<std::string>& args, std::ostream& help_out);
  std::string Help() const;

 private:
  using Target =
      std::variant<std::string*, int*, int64_t*, double*, bool*, std::vector<std::string>*>;
  struct Option {
    std::string name;
    Target target;
    std::string help;
    bool required = false;
    bool positional = false;
    bool seen = false;
    std::string default_text;
  };
  Option* Find(const std::string& name);
  void Assign(Option& option, const std::string& value);
  void Add(const std::string& name, Target target, const std::string& help, bool required,
           bool positional);

  std::string command_;
  std::string summary_;
  std::vector<Option> options_;
  std::vector<std::pair<std::string, std::string>> former_names_;  // (former, current)
};

}  // namespace visloc
