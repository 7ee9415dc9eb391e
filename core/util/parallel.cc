#include "core/util/parallel.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <thread>
#include <vector>

namespace visloc {

int ResolveThreads(int requested) {
  if (requested > 0) return requested;
  return std::max(1u, std::thread::hardware_concurrency());
}

namespace {

// Runs body(0) on the calling thread and body(1) ... body(count - 1) on as many helpers; returns
// when all have, rethrowing the exception of the lowest-numbered body that threw.
void RunOnThreads(int count, const std::function<void(int thread)>& body) {
  std::vector<std::exception_ptr> errors(count);
  const auto run = [&](int thread) {
    try {
      body(thread);
    } catch (...) {
      errors[thread] = std::current_exception();
    }
  };
  std::vector<std::thread> helpers;
  for (int thread = 1; thread < count; ++thread) helpers.emplace_back(run, thread);
  run(0);
  for (std::thread& helper : helpers) helper.join();
  for (const std::exception_ptr& error : errors) {
    if (error) std::rethrow_exception(error);
  }
}

}  // namespace

std::pair<int, int> PartRange(int n, int part, int parts) {
  return {static_cast<int>(static_cast<long>(n) * part / parts),
          static_cast<int>(static_cast<long>(n) * (part + 1) / parts)};
}

void ParallelRanges(int n, int threads, const std::function<void(int begin, int end)>& fn) {
  if (n <= 0) return;
  const int parts = std::clamp(threads, 1, n);
  RunOnThreads(parts, [&](int part) {
    const auto [begin, end] = PartRange(n, part, parts);
    fn(begin, end);
  });
}

void ParallelChunks(int n, int threads, int chunk,
                    const std::function<void(int begin, int end)>& fn) {
  if (n <= 0) return;
  chunk = std::max(chunk, 1);
  const int chunks = (n + chunk - 1) / chunk;
  std::atomic<int> next{0};
  RunOnThreads(std::clamp(threads, 1, chunks), [&](int) {
    // A range that throws does not stop this thread taking the rest; its first error is
    // rethrown once they are done.
    std::exception_ptr error;
    for (int c = next++; c < chunks; c = next++) {
      try {
        fn(c * chunk, std::min(n, (c + 1) * chunk));
      } catch (...) {
        if (!error) error = std::current_exception();
      }
    }
    if (error) std::rethrow_exception(error);
  });
}

void RunBoth(int threads, const std::function<void()>& first, const std::function<void()>& second) {
  ParallelRanges(2, threads, [&](int begin, int end) {
    for (int i = begin; i < end; ++i) (i == 0 ? first : second)();
  });
}

}  // namespace visloc
