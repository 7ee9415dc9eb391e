#pragma once
// The CPU priority of the calling thread alone (Linux: a thread is a task with its own nice).
//
// A server's real-time work (localizing robots' frames) shares the cores with work that can wait:
// the operator's page, metrics scrapes, a map's localizability grid. Run on threads a few nice
// levels down, that work takes only what the real-time threads leave, instead of delaying every
// robot's frames while a page loads.

namespace visloc {

// Adds `increment` (> 0) to the calling thread's nice value, at most to 19; other threads keep
// theirs. Lowering a priority needs no privilege. Returns the thread's nice value after.
int LowerThisThreadsPriority(int increment);

// The calling thread's nice value.
int ThisThreadsNice();

}  // namespace visloc
