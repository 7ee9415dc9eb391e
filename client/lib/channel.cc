#include "client/lib/channel.h"

namespace visloc::client {
namespace {

std::shared_ptr<grpc::ChannelCredentials> ChannelCredentials(const Credentials& c) {
  if (c.tls_ca_pem.empty()) return grpc::InsecureChannelCredentials();
  grpc::SslCredentialsOptions tls;
  tls.pem_root_certs = c.tls_ca_pem;
  tls.pem_cert_chain = c.tls_cert_pem;
  tls.pem_private_key = c.tls_key_pem;
  return grpc::SslCredentials(tls);
}

}  // namespace

std::string NextReplicaFirst(const std::string& target) {
  const size_t colon = target.find(':');
  const std::string scheme = colon == std::string::npos ? "" : target.substr(0, colon);
  const size_t comma = target.find(',');
  if ((scheme != "ipv4" && scheme != "ipv6") || comma == std::string::npos) return target;
  const std::string first = target.substr(colon + 1, comma - colon - 1);
  return scheme + ":" + target.substr(comma + 1) + "," + first;
}

std::shared_ptr<grpc::Channel> NewStreamChannel(const std::string& server,
                                                const Credentials& credentials,
                                                const ChannelTiming& timing) {
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  args.SetInt(GRPC_ARG_KEEPALIVE_TIME_MS, static_cast<int>(timing.keepalive_time.count()));
  args.SetInt(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, static_cast<int>(timing.keepalive_timeout.count()));
  args.SetInt(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 0);
  args.SetInt(GRPC_ARG_HTTP2_MAX_PINGS_WITHOUT_DATA, 0);
  // The channel's own reconnection must not wait longer than ours.
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS,
              static_cast<int>(timing.backoff_initial.count()));
  args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, static_cast<int>(timing.backoff_initial.count()));
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, static_cast<int>(timing.backoff_max.count()));
  args.SetMaxReceiveMessageSize(kMaxReceiveMessageBytes);
  // Replicas (several addresses): the first in the list's order that connects, a dead one
  // skipped. The order is the caller's (shuffled per robot, turned after a capacity refusal);
  // round_robin would ignore it and send a stream to whichever replica connected first, a
  // refused robot back to the full replica.
  args.SetLoadBalancingPolicyName("pick_first");
  if (!credentials.tls_target_name.empty()) {
    args.SetSslTargetNameOverride(credentials.tls_target_name);
  }
  return grpc::CreateCustomChannel(server, ChannelCredentials(credentials), args);
}

}  // namespace visloc::client
