#pragma once
// The project's version, as CMake's project() declares it: what `--version` prints and what a map
// file records as its builder. One place, so the binaries and the maps cannot disagree.

namespace visloc {

// "MAJOR.MINOR.PATCH".
const char* VislocVersion();

}  // namespace visloc
