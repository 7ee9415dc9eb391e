#include "core/util/parallel.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace visloc {

int ResolveThreads(int requested) {
  if (requested > 0) return requested;
  return std::max(1u, std::thread::hardware_concurrency());
}

void ParallelRanges(int n, int threads, const std::function<void(int begin, int end)>& fn) {
  if (n <= 0) return;
  const int parts = std::clamp(threads, 1, n);
  std::vector<std::exception_ptr> errors(parts);
  const auto run = [&](int part) {
    try {
      fn(static_cast<int>(static_cast<long>(n) * part / parts),
         static_cast<int>(static_cast<long>(n) * (part + 1) / parts));
    } catch (...) {
      errors[part] = std::current_exception();
    }
  };
  std::vector<std::thread> helpers;
  for (int part = 1; part < parts; ++part) helpers.emplace_back(run, part);
  run(0);
  for (std::thread& helper : helpers) helper.join();
  for (const std::exception_ptr& error : errors) {
    if (error) std::rethrow_exception(error);
  }
}

void ParallelChunks(int n, int threads, int chunk,
                    const std::function<void(int begin, int end)>& fn) {
  if (n <= 0) return;
  chunk = std::max(chunk, 1);
  const int chunks = (n + chunk - 1) / chunk;
  std::atomic<int> next{0};
  std::exception_ptr error;
  std::mutex error_mutex;
  const auto take = [&] {
    for (int c = next++; c < chunks; c = next++) {
      try {
        fn(c * chunk, std::min(n, (c + 1) * chunk));
      } catch (...) {
        const std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
      }
    }
  };
  std::vector<std::thread> helpers;
  for (int t = 1; t < std::clamp(threads, 1, chunks); ++t) helpers.emplace_back(take);
  take();
  for (std::thread& helper : helpers) helper.join();
  if (error) std::rethrow_exception(error);
}

void RunBoth(int threads, const std::function<void()>& first, const std::function<void()>& second) {
  ParallelRanges(2, threads, [&](int begin, int end) {
    for (int i = begin; i < end; ++i) (i == 0 ? first : second)();
  });
}

}  // namespace visloc
