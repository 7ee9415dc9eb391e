#pragma once
// Spreading robots over server replicas from the client side. A fleet that outgrows one
// server runs several visloc-server replicas behind one DNS name (a Kubernetes headless
// service: one address per replica) or names them as a list ("ipv4:10.0.0.5:50051,10.0.0.6:50051").
// A robot session (one Localize stream, which never leaves the replica it started on) asks the
// list's replicas in order: the first that connects serves it, a dead one is skipped, and one
// at capacity sends it on to the next (client/lib/channel.h). Every robot gets its own shuffled
// list, so robots spread over the replicas; the one-off calls of the CLI balance theirs with
// gRPC's round_robin.

#include <random>
#include <string>
#include <vector>

namespace visloc::cli {

// Socket addresses "HOST:PORT" of one family a name resolves to, IPv4 preferred when it has
// at least two (the loopback name "localhost" resolves to one IPv4 and one IPv6 address: that
// is one server, not two replicas).
std::vector<std::string> ResolveReplicas(const std::string& host, const std::string& port);

// The gRPC target for `server`: an explicit "ipv4:"/"ipv6:" list, or a HOST:PORT (optionally
// "dns:///HOST:PORT") that resolves to two or more addresses, becomes a shuffled address list
// (shuffled by `rng`; Connection::ToLibrary draws a new one for each robot).
// Anything else (one address, a name that does not resolve, other schemes) is returned as is,
// so gRPC's own resolver reports failures and re-resolves. `resolve` is ResolveReplicas in
// production and a table in tests.
using ResolveFn = std::vector<std::string> (*)(const std::string& host, const std::string& port);
struct ReplicaTarget {
  std::string target;
  // The name the replicas' TLS certificates are issued for, when `target` replaced it by
  // addresses; empty otherwise.
  std::string tls_name;
};
ReplicaTarget ChooseReplicaTarget(const std::string& server, std::mt19937* rng,
                                  ResolveFn resolve = &ResolveReplicas);

}  // namespace visloc::cli
