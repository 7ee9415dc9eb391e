#pragma once
// Work split over a few threads, for the stages a map build spends its time in (one build is
// one job: on a 2-core machine it may use both). Threads are started per call and joined before
// it returns: a stereo frame costs milliseconds, a thread's start microseconds. Results never
// depend on the thread count: each index is the same computation on whichever thread runs it.

#include <functional>
#include <utility>

namespace visloc {

// The threads a caller asking for `requested` gets: `requested` itself when positive, else
// every core the machine reports (at least 1).
int ResolveThreads(int requested);

// Part `part` of [0, n) cut into `parts` contiguous ranges of sizes differing by at most one:
// {begin, end}.
std::pair<int, int> PartRange(int n, int part, int parts);

// Calls fn(begin, end) on contiguous ranges that cover [0, n), one range per thread (at most
// `threads`, none empty), the first on the calling thread. An exception thrown by any range is
// rethrown here after all have finished.
void ParallelRanges(int n, int threads, const std::function<void(int begin, int end)>& fn);

// Calls fn(begin, end) on the consecutive ranges of `chunk` indices (the last one shorter) that
// cover [0, n), which up to `threads` threads, the calling one among them, take in turn as each
// finishes its last: where the cost varies along the indices, no thread is left with the slow
// end alone. An exception thrown by any range is rethrown here after all have finished (the
// other ranges still run).
void ParallelChunks(int n, int threads, int chunk,
                    const std::function<void(int begin, int end)>& fn);

// Runs `first` on the calling thread and `second` beside it on another (one after the other
// when threads < 2); returns when both have, rethrowing the first exception either threw.
void RunBoth(int threads, const std::function<void()>& first, const std::function<void()>& second);

}  // namespace visloc
