#include "client/outcome.h"

#include <iostream>

#include "core/util/json.h"

namespace visloc::cli {

int PrintOutcome(bool json, const std::string& sentence, const OutcomeFields& fields) {
  if (!json) {
    std::cout << sentence << std::endl;
    return 0;
  }
  JsonWriter writer;
  writer.BeginObject().Field("ok", true);
  for (const auto& [key, value] : fields) {
    writer.Key(key);
    std::visit([&writer](const auto& v) { writer.Value(v); }, value);
  }
  writer.EndObject();
  std::cout << writer.str() << std::endl;
  return 0;
}

}  // namespace visloc::cli
