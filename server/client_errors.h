#pragma once
// What a client may see of a server-side failure. Library errors name files by their server
// paths (the maps folder, staged uploads) and checks name source files and lines: useful in the
// server log, a leak on the wire. Every error a service returns goes through here; the full
// text goes to the log.

#include <grpcpp/grpcpp.h>

#include <exception>
#include <string>

namespace visloc::server {

// `message` with every absolute path replaced by what it means to a client: "map 'NAME'" for a
// map file NAME.db, "map 'NAME' (staged upload)" for a staging temporary beside it, "the maps
// folder" for a folder, "a server file" otherwise.
std::string RedactForClient(const std::string& message);

// The gRPC status for an exception caught in a service: NotFoundError -> NOT_FOUND,
// InputError -> INVALID_ARGUMENT (redacted message); anything else is a bug or a resource
// failure -> INTERNAL with a reference number only, and an "internal_error" log line holding the
// reference, `where` and the full text.
grpc::Status StatusFromException(const std::exception& e, const char* where);

// The reference number that log line and the client message share, for an unexpected
// exception; also logs it.
std::string LogInternalError(const std::exception& e, const char* where);

}  // namespace visloc::server
