#include "client/replicas.h"

#include <netdb.h>
#include <sys/socket.h>
#include <algorithm>
#include <memory>

#include <arpa/inet.h>

#include "core/util/strings.h"

namespace visloc::cli {
namespace {

std::string JoinShuffled(const std::string& scheme, std::vector<std::string> addresses,
                         std::mt19937* rng) {
  std::shuffle(addresses.begin(), addresses.end(), *rng);
  std::string target = scheme + ":";
  for (size_t i = 0; i < addresses.size(); ++i) target += (i ? "," : "") + addresses[i];
  return target;
}

}  // namespace

std::vector<std::string> ResolveReplicas(const std::string& host, const std::string& port) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  if (getaddrinfo(host.c_str(), port.c_str(), &hints, &found) != 0) return {};
  std::unique_ptr<addrinfo, decltype(&freeaddrinfo)> owner(found, &freeaddrinfo);
  std::vector<std::string> v4, v6;
  for (const addrinfo* a = found; a != nullptr; a = a->ai_next) {
    char text[INET6_ADDRSTRLEN] = {};
    if (a->ai_family == AF_INET) {
      inet_ntop(AF_INET, &reinterpret_cast<const sockaddr_in*>(a->ai_addr)->sin_addr, text,
                sizeof(text));
      v4.push_back(std::string(text) + ":" + port);
    } else if (a->ai_family == AF_INET6) {
      inet_ntop(AF_INET6, &reinterpret_cast<const sockaddr_in6*>(a->ai_addr)->sin6_addr, text,
                sizeof(text));
      v6.push_back("[" + std::string(text) + "]:" + port);
    }
  }
  for (auto* list : {&v4, &v6}) {  // getaddrinfo repeats an address once per protocol.
    std::sort(list->begin(), list->end());
    list->erase(std::unique(list->begin(), list->end()), list->end());
  }
  if (v4.size() >= 2 || v6.size() < 2) return v4;
  return v6;
}

ReplicaTarget ChooseReplicaTarget(const std::string& server, std::mt19937* rng, ResolveFn resolve) {
  for (const std::string scheme : {"ipv4", "ipv6"}) {
    if (StartsWith(server, scheme + ":")) {
      return {JoinShuffled(scheme, Split(server.substr(scheme.size() + 1), ','), rng), ""};
    }
  }
  std::string host_port = server;
  if (StartsWith(host_port, "dns:///")) host_port = host_port.substr(7);
  const size_t colon = host_port.rfind(':');
  // Other schemes (unix:, dns://AUTHORITY/...) and bracketed IPv6 literals are one address.
  if (colon == std::string::npos || host_port.find('/') != std::string::npos ||
      host_port.front() == '[') {
    return {server, ""};
  }
  const std::string host = host_port.substr(0, colon);
  const std::vector<std::string> addresses = resolve(host, host_port.substr(colon + 1));
  if (addresses.size() < 2) return {server, ""};
  return {JoinShuffled(StartsWith(addresses.front(), "[") ? "ipv6" : "ipv4", addresses, rng), host};
}

}  // namespace visloc::cli
