#include "server/client_errors.h"

#include <atomic>
#include <filesystem>
#include <regex>

#include "core/util/check.h"
#include "server/log.h"

namespace visloc::server {
namespace {

namespace fs = std::filesystem;

std::string DescribePath(const std::string& path) {
  const std::string filename = fs::path(path).filename().string();
  static const std::regex map_file(R"(([A-Za-z0-9_.-]+)\.db)");
  // Staging temporaries: ".NAME.db.tmp-PID-N" (mapstore's TemporaryPathBeside).
  static const std::regex staged(R"(\.([A-Za-z0-9_.-]+)\.db\.tmp-[0-9-]+)");
  std::smatch m;
  if (std::regex_match(filename, m, staged)) return "map '" + m[1].str() + "' (staged upload)";
  if (std::regex_match(filename, m, map_file)) return "map '" + m[1].str() + "'";
  std::error_code ignored;
  if (fs::is_directory(path, ignored)) return "the maps folder";
  return "a server file";
}

std::atomic<uint64_t> next_reference{1};

}  // namespace

std::string RedactForClient(const std::string& message) {
  // An absolute path: a slash at the start or after a space, quote or parenthesis, up to a
  // space, quote, colon or comma.
  static const std::regex path(R"((^|[\s'"(])(/[^\s'":,]+))");
  std::string out;
  auto begin = message.cbegin();
  for (std::sregex_iterator it(message.begin(), message.end(), path), end; it != end; ++it) {
    const std::smatch& m = *it;
    out.append(begin, m[2].first);
    out += DescribePath(m[2].str());
    begin = m[2].second;
  }
  out.append(begin, message.cend());
  return out;
}

std::string LogInternalError(const std::exception& e, const char* where) {
  const std::string reference = std::to_string(next_reference++);
  Log("internal_error", {{"reference", reference}, {"where", where}, {"what", e.what()}});
  return reference;
}

grpc::Status StatusFromException(const std::exception& e, const char* where) {
  if (dynamic_cast<const NotFoundError*>(&e)) {
    return grpc::Status(grpc::StatusCode::NOT_FOUND, RedactForClient(e.what()));
  }
  if (dynamic_cast<const InputError*>(&e)) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, RedactForClient(e.what()));
  }
  return grpc::Status(
      grpc::StatusCode::INTERNAL,
      "internal server error (reference " + LogInternalError(e, where) + " in the server log)");
}

}  // namespace visloc::server
