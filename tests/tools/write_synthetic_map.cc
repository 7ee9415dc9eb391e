// Test tool: writes a synthetic map with SaveMap, so a test can kill a real writer process
// mid-write, or a big map for the operator page. Usage: write_synthetic_map PATH POINTS SEED
// [KEYFRAMES [NAME]] (default: POINTS / 100 keyframes, named "crash"). It creates PATH.ready when it starts
// writing.
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

#include "core/map/synthetic_map.h"
#include "mapstore/map_store.h"

int main(int argc, char** argv) {
  if (argc < 4 || argc > 6) {
    std::fprintf(stderr, "usage: write_synthetic_map PATH POINTS SEED [KEYFRAMES [NAME]]\n");
    return 2;
  }
  try {
    visloc::SyntheticMapOptions options;
    options.points = std::atoi(argv[2]);
    options.keyframes = argc > 4 ? std::atoi(argv[4]) : std::max(4, options.points / 100);
    options.seed = std::strtoull(argv[3], nullptr, 10);
    visloc::Map map = visloc::MakeSyntheticMap(options);
    map.metadata.name = argc > 5 ? argv[5] : "crash";
    // Tell a watching test that the write starts now, so it can time its kill.
    std::fclose(std::fopen((std::string(argv[1]) + ".ready").c_str(), "w"));
    visloc::mapstore::SaveMap(map, argv[1]);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "write_synthetic_map: %s\n", e.what());
    return 1;
  }
  return 0;
}
