// visloc-link-proxy: the test link emulator (tests/support/link_proxy.h) as a command, for
// scripts that measure visloc through a bad link (scripts/robot-link.sh). Bounded: it exits
// after --seconds.
//
//   visloc-link-proxy --upstream 127.0.0.1:PORT [--latency-ms L] [--jitter-ms J] [--mbit B]
//                     [--stall-every-s S --stall-ms MS] [--cut-every-s S --cut-ms MS [--cuts N]]
//                     [--seconds T]
// Prints "listening on ADDRESS" once ready.

#include <chrono>
#include <cstdio>
#include <iostream>
#include <thread>

#include "core/util/args.h"
#include "core/util/check.h"
#include "tests/support/link_proxy.h"

int main(int argc, char** argv) {
  std::string upstream;
  visloc::testing::LinkProfile profile;
  double stall_every_s = 0, stall_ms = 0, cut_every_s = 0, cut_ms = 0, seconds = 60;
  int max_cuts = 0;
  visloc::ArgParser parser("visloc-link-proxy",
                           "A loopback TCP proxy that adds latency and jitter, caps bandwidth, "
                           "and stalls or cuts the link periodically.");
  parser.AddFlag("upstream", &upstream, "the server's address HOST:PORT", true);
  parser.AddFlag("latency-ms", &profile.latency_ms, "one-way latency");
  parser.AddFlag("jitter-ms", &profile.jitter_ms, "uniform extra latency per chunk");
  parser.AddFlag("mbit", &profile.bandwidth_mbit_s, "bandwidth each way (0: unlimited)");
  parser.AddFlag("stall-every-s", &stall_every_s, "a stall this often (0: never)");
  parser.AddFlag("stall-ms", &stall_ms, "how long each stall lasts");
  parser.AddFlag("cut-every-s", &cut_every_s, "a cut this often (0: never)");
  parser.AddFlag("cut-ms", &cut_ms, "how long each cut lasts");
  parser.AddFlag("cuts", &max_cuts, "at most this many cuts (0: no limit)");
  parser.AddFlag("seconds", &seconds, "exit after this long");
  try {
    if (!parser.Parse(std::vector<std::string>(argv + 1, argv + argc), std::cout)) return 0;
    visloc::testing::LinkProxy proxy(upstream, profile);
    std::printf("listening on %s\n", proxy.address().c_str());
    std::fflush(stdout);
    using Clock = std::chrono::steady_clock;
    const Clock::time_point start = Clock::now(), end = start + std::chrono::milliseconds(
                                                                    static_cast<int64_t>(seconds * 1000));
    Clock::time_point next_stall = start + std::chrono::milliseconds(static_cast<int64_t>(stall_every_s * 1000));
    Clock::time_point next_cut = start + std::chrono::milliseconds(static_cast<int64_t>(cut_every_s * 1000));
    int cuts = 0;
    while (Clock::now() < end) {
      const Clock::time_point now = Clock::now();
      if (stall_every_s > 0 && now >= next_stall) {
        proxy.Stall(std::chrono::milliseconds(static_cast<int64_t>(stall_ms)));
        next_stall += std::chrono::milliseconds(static_cast<int64_t>(stall_every_s * 1000));
      }
      if (cut_every_s > 0 && now >= next_cut && (max_cuts == 0 || cuts < max_cuts)) {
        ++cuts;
        proxy.Cut(std::chrono::milliseconds(static_cast<int64_t>(cut_ms)));
        // The cut's end, for scripts timing the reconnection (milliseconds since the epoch).
        const auto back = std::chrono::system_clock::now() +
                          std::chrono::milliseconds(static_cast<int64_t>(cut_ms));
        std::printf("cut until %lld\n",
                    static_cast<long long>(std::chrono::duration_cast<std::chrono::milliseconds>(
                                               back.time_since_epoch())
                                               .count()));
        std::fflush(stdout);
        next_cut += std::chrono::milliseconds(static_cast<int64_t>(cut_every_s * 1000));
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return 0;
  } catch (const visloc::UsageError& e) {
    std::fprintf(stderr, "visloc-link-proxy: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "visloc-link-proxy: %s\n", e.what());
    return 1;
  }
}
