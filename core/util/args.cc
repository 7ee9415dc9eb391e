#include "core/util/args.h"

#include <sstream>

#include "core/util/check.h"
#include "core/util/strings.h"

namespace visloc {
namespace {

std::string DefaultText(const std::variant<std::string*, int*, int64_t*, double*, bool*,
                                           std::vector<std::string>*>& t) {
  return std::visit(
      [](auto* ptr) -> std::string {
        using T = std::remove_pointer_t<decltype(ptr)>;
        if constexpr (std::is_same_v<T, bool> || std::is_same_v<T, std::vector<std::string>>) {
          return "";
        } else if constexpr (std::is_same_v<T, std::string>) {
          return ptr->empty() ? "" : *ptr;
        } else {
          std::ostringstream out;
          out << *ptr;
          return out.str();
        }
      },
      t);
}

}  // namespace

ArgParser::ArgParser(std::string command, std::string summary)
    : command_(std::move(command)), summary_(std::move(summary)) {}

void ArgParser::Add(const std::string& name, Target target, const std::string& help, bool required,
                    bool positional) {
  VISLOC_CHECK(Find(name) == nullptr, "duplicate option ", name);
  Option option;
  option.name = name;
  option.target = target;
  option.help = help;
  option.required = required;
  option.positional = positional;
  if (!required) option.default_text = DefaultText(target);
  options_.push_back(std::move(option));
}

void ArgParser::AddFlag(const std::string& name, std::string* target, const std::string& help,
                        bool required) {
  Add(name, target, help, required, /*positional=*/false);
}
void ArgParser::AddFlag(const std::string& name, int* target, const std::string& help,
                        bool required) {
  Add(name, target, help, required, /*positional=*/false);
}
void ArgParser::AddFlag(const std::string& name, int64_t* target, const std::string& help,
                        bool required) {
  Add(name, target, help, required, /*positional=*/false);
}
void ArgParser::AddFlag(const std::string& name, double* target, const std::string& help,
                        bool required) {
  Add(name, target, help, required, /*positional=*/false);
}
void ArgParser::SetDefaultText(const std::string& name, const std::string& text) {
  Option* option = Find(name);
  VISLOC_CHECK(option != nullptr, "no option ", name);
  option->default_text = text;
}
void ArgParser::AddList(const std::string& name, std::vector<std::string>* target,
                        const std::string& help, bool required) {
  Add(name, target, help, required, /*positional=*/false);
}
void ArgParser::AddSwitch(const std::string& name, bool* target, const std::string& help) {
  Add(name, target, help, /*required=*/false, /*positional=*/false);
}
void ArgParser::AddPositional(const std::string& name, std::string* target, const std::string& help,
                              bool required) {
  Add(name, target, help, required, /*positional=*/true);
}

ArgParser::Option* ArgParser::Find(const std::string& name) {
  for (Option& option : options_) {
    if (option.name == name) return &option;
  }
  for (const auto& [former, current] : former_names_) {
    if (former == name) return Find(current);
  }
  return nullptr;
}

void ArgParser::AddFormerName(const std::string& former, const std::string& name) {
  VISLOC_CHECK(Find(former) == nullptr, "duplicate option ", former);
  VISLOC_CHECK(Find(name) != nullptr, "no option ", name, " for its former name ", former);
  former_names_.emplace_back(former, name);
}

void ArgParser::Assign(Option& option, const std::string& value) {
  const std::string label = option.positional ? option.name : "--" + option.name;
  std::visit(
      [&](auto* ptr) {
        using T = std::remove_pointer_t<decltype(ptr)>;
        if constexpr (std::is_same_v<T, std::string>) {
          *ptr = value;
        } else if constexpr (std::is_same_v<T, std::vector<std::string>>) {
          ptr->push_back(value);
        } else if constexpr (std::is_same_v<T, bool>) {
          *ptr = true;
        } else if constexpr (std::is_same_v<T, double>) {
          const auto parsed = ParseDouble(value);
          if (!parsed) throw UsageError(StrCat(label, " expects a number, got '", value, "'"));
          *ptr = *parsed;
        } else {
          const auto parsed = ParseInt64(value);
          if (!parsed) throw UsageError(StrCat(label, " expects an integer, got '", value, "'"));
          *ptr = static_cast<T>(*parsed);
        }
      },
      option.target);
  option.seen = true;
}

bool ArgParser::Parse(const std::vector<std::string>& args, std::ostream& help_out) {
  size_t next_positional = 0;
  std::vector<Option*> positionals;
  for (Option& option : options_) {
    if (option.positional) positionals.push_back(&option);
  }
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (arg == "--help" || arg == "-h") {
      help_out << Help();
      return false;
    }
    if (StartsWith(arg, "--")) {
      std::string name = arg.substr(2);
      std::optional<std::string> value;
      if (const size_t eq = name.find('='); eq != std::string::npos) {
        value = name.substr(eq + 1);
        name = name.substr(0, eq);
      }
      Option* option = Find(name);
      if (option == nullptr || option->positional) {
        throw UsageError(StrCat("unknown option --", name));
      }
      if (std::holds_alternative<bool*>(option->target)) {
        if (value) throw UsageError(StrCat("--", name, " takes no value"));
        Assign(*option, "");
        continue;
      }
      if (!value) {
        if (i + 1 >= args.size()) throw UsageError(StrCat("--", name, " needs a value"));
        value = args[++i];
      }
      Assign(*option, *value);
      if (std::holds_alternative<std::vector<std::string>*>(option->target)) {
        while (i + 1 < args.size() && !StartsWith(args[i + 1], "--")) Assign(*option, args[++i]);
      }
      continue;
    }
    if (next_positional >= positionals.size()) {
      throw UsageError(StrCat("unexpected argument '", arg, "'"));
    }
    Assign(*positionals[next_positional++], arg);
  }
  for (const Option& option : options_) {
    if (option.required && !option.seen) {
      throw UsageError(option.positional ? StrCat("missing ", option.name)
                                         : StrCat("missing --", option.name));
    }
  }
  return true;
}

std::string ArgParser::Help() const {
  std::ostringstream out;
  out << "usage: " << command_;
  for (const Option& option : options_) {
    if (option.positional)
      out << (option.required ? " " : " [") << option.name << (option.required ? "" : "]");
  }
  out << " [options]\n\n" << summary_ << "\n\noptions:\n";
  for (const Option& option : options_) {
    std::string label = option.positional ? option.name : "--" + option.name;
    if (std::holds_alternative<std::vector<std::string>*>(option.target)) {
      label += " VALUE...";
    } else if (!option.positional && !std::holds_alternative<bool*>(option.target)) {
      label += " VALUE";
    }
    out << "  " << label;
    for (size_t pad = label.size(); pad < 26; ++pad) out << ' ';
    out << ' ' << option.help;
    if (option.required) out << " (required)";
    if (!option.default_text.empty()) out << " [default: " << option.default_text << "]";
    out << "\n";
  }
  out << "  --help                     show this help\n";
  return out.str();
}

}  // namespace visloc
