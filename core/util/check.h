#pragma once
// Fail-fast checks for programmer and configuration errors. They throw (never abort), so a
// server that calls library code with a bad value answers with an error and keeps serving.

#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

namespace visloc {

// Concatenates any streamable values: StrCat("frame ", 3, " of ", n).
template <typename... Args>
std::string StrCat(Args&&... args) {
  std::ostringstream out;
  (out << ... << std::forward<Args>(args));
  return out.str();
}

// Thrown for invalid arguments and broken invariants (a bug or a misconfiguration).
class CheckError : public std::logic_error {
 public:
  using std::logic_error::logic_error;
};

// Thrown for bad input data: malformed files, unreadable images, inconsistent datasets.
// The message names the file and, where there is one, the line.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Bad input of one kind: it names something (a map, a file) that does not exist. Services map
// it to "not found" rather than "invalid argument".
class NotFoundError : public InputError {
 public:
  using InputError::InputError;
};

namespace internal {
[[noreturn]] void ThrowCheckFailure(const char* file, int line, const char* condition,
                                    const std::string& message);
}  // namespace internal

}  // namespace visloc

// VISLOC_CHECK(cond, "message parts", value, ...) throws visloc::CheckError naming the
// condition, the source location and the message. The message is required: it should name
// the offending value.
#define VISLOC_CHECK(cond, ...)                                             \
  do {                                                                      \
    if (!(cond)) {                                                          \
      ::visloc::internal::ThrowCheckFailure(__FILE__, __LINE__, #cond,      \
                                            ::visloc::StrCat(__VA_ARGS__)); \
    }                                                                       \
  } while (false)
