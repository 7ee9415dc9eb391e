#include "core/util/check.h"

#include <cstring>

namespace visloc::internal {

void ThrowCheckFailure(const char* file, int line, const char* condition,
                       const std::string& message) {
  const char* base = std::strrchr(file, '/');
  std::string text = StrCat("check failed at ", base ? base + 1 : file, ":", line, ": ", condition);
  if (!message.empty()) text += StrCat(" (", message, ")");
  throw CheckError(text);
}

}  // namespace visloc::internal
