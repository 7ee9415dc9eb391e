#include "client/replicas.h"

#include <set>

#include <gtest/gtest.h>

#include "core/util/strings.h"

namespace visloc::cli {
namespace {

// Three replicas behind "fleet", one address behind "solo", nothing behind anything else.
std::vector<std::string> FakeDns(const std::string& host, const std::string& port) {
  if (host == "fleet") return {"10.0.0.5:" + port, "10.0.0.6:" + port, "10.0.0.7:" + port};
  if (host == "solo") return {"10.0.0.9:" + port};
  return {};
}

std::set<std::string> Addresses(const std::string& target, const std::string& scheme) {
  EXPECT_TRUE(StartsWith(target, scheme + ":")) << target;
  const auto fields = Split(target.substr(scheme.size() + 1), ',');
  return {fields.begin(), fields.end()};
}

TEST(ReplicaTargetTest, NameWithSeveralAddressesBecomesTheirList) {
  std::mt19937 rng(1);
  const ReplicaTarget chosen = ChooseReplicaTarget("fleet:50051", &rng, &FakeDns);
  EXPECT_EQ(Addresses(chosen.target, "ipv4"),
            (std::set<std::string>{"10.0.0.5:50051", "10.0.0.6:50051", "10.0.0.7:50051"}));
  EXPECT_EQ(chosen.tls_name, "fleet");  // Certificates name the service, not the pod IPs.
  EXPECT_EQ(ChooseReplicaTarget("dns:///fleet:7000", &rng, &FakeDns).tls_name, "fleet");
}

TEST(ReplicaTargetTest, EachProcessStartsOnADifferentReplica) {
  // The first address is where a process's first session goes; over many processes (seeds)
  // every replica must come first about equally often.
  std::map<std::string, int> first;
  for (unsigned seed = 0; seed < 300; ++seed) {
    std::mt19937 rng(seed);
    const std::string target = ChooseReplicaTarget("fleet:50051", &rng, &FakeDns).target;
    ++first[Split(target.substr(5), ',').front()];
  }
  ASSERT_EQ(first.size(), 3u);
  for (const auto& [address, count] : first) EXPECT_GT(count, 60) << address;
}

TEST(ReplicaTargetTest, ExplicitListsAreShuffledNotResolved) {
  std::mt19937 rng(2);
  const ReplicaTarget chosen =
      ChooseReplicaTarget("ipv4:127.0.0.1:5001,127.0.0.1:5002", &rng, &FakeDns);
  EXPECT_EQ(Addresses(chosen.target, "ipv4"),
            (std::set<std::string>{"127.0.0.1:5001", "127.0.0.1:5002"}));
  EXPECT_EQ(chosen.tls_name, "");
}

TEST(ReplicaTargetTest, SingleAddressesAndOtherSchemesAreLeftToGrpc) {
  std::mt19937 rng(3);
  for (const std::string server : {"solo:50051", "nowhere:50051", "127.0.0.1:50051", "[::1]:50051",
                                   "unix:/run/visloc.sock", "no-port"}) {
    EXPECT_EQ(ChooseReplicaTarget(server, &rng, &FakeDns).target, server);
  }
}

TEST(ReplicaTargetTest, LocalhostIsOneServer) {
  // One IPv4 and one IPv6 loopback address: the same server twice, never a replica list.
  EXPECT_LE(ResolveReplicas("localhost", "50051").size(), 1u);
  std::mt19937 rng(4);
  EXPECT_EQ(ChooseReplicaTarget("localhost:50051", &rng).target, "localhost:50051");
}

}  // namespace
}  // namespace visloc::cli
