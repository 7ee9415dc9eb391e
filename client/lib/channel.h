#pragma once
// The channel a client stream runs on (localization sessions, mapping sessions, one-off calls):
// a fresh connection per stream, since after a stall the old one may be a dead TCP connection
// that gRPC has not noticed yet (a local subchannel pool); keepalive; the channel's own
// reconnection no slower than the caller's; replicas in the list's order; TLS from PEM strings.

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <memory>
#include <string>

#include "visloc/client/session.h"

namespace visloc::client {

struct ChannelTiming {
  std::chrono::milliseconds keepalive_time{10000};
  std::chrono::milliseconds keepalive_timeout{5000};
  std::chrono::milliseconds backoff_initial{50};
  std::chrono::milliseconds backoff_max{500};
};

// The bearer token, when there is one, as the call's authorization metadata.
inline void Authorize(grpc::ClientContext* context, const Credentials& credentials) {
  if (!credentials.token.empty()) {
    context->AddMetadata("authorization", "Bearer " + credentials.token);
  }
}

// A replica list ("ipv4:A:PORT,B:PORT", "ipv6:...") with its first address moved to the end, so
// a new stream channel (pick_first: the list's order) starts at the next replica; any other
// target unchanged. A session refused by a replica at capacity asks the next one.
std::string NextReplicaFirst(const std::string& target);

std::shared_ptr<grpc::Channel> NewStreamChannel(const std::string& server,
                                                const Credentials& credentials,
                                                const ChannelTiming& timing);

}  // namespace visloc::client
