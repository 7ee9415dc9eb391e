// Map loading and saving speed (Google Benchmark). Run:
//   build/mapstore/map_store_benchmark --benchmark_counters_tabular=true
// Reports points loaded per second from a warm page cache; the target is >= 1e6 points/s.

#include <benchmark/benchmark.h>

#include <filesystem>
#include <map>

#include "core/map/localization_map.h"
#include "core/map/synthetic_map.h"
#include "core/util/temp_dir.h"
#include "mapstore/map_store.h"

namespace visloc::mapstore {
namespace {

// One map file per size, written once per run.
const std::string& MapFile(int points) {
  static TempDir dir("visloc-bench");
  static std::map<int, std::string> files;
  auto& path = files[points];
  if (path.empty()) {
    SyntheticMapOptions options;
    options.points = points;
    options.keyframes = std::max(10, points / 100);
    Map map = MakeSyntheticMap(options);
    map.metadata.name = "bench";
    path = dir.File("bench-" + std::to_string(points) + ".db");
    SaveMap(map, path);
  }
  return path;
}

void BM_LoadMap(benchmark::State& state) {
  const int points = static_cast<int>(state.range(0));
  const std::string& path = MapFile(points);
  LoadMap(path);  // warm the page cache
  for (auto _ : state) benchmark::DoNotOptimize(LoadMap(path));
  state.counters["points_per_s"] = benchmark::Counter(
      static_cast<double>(points) * state.iterations(), benchmark::Counter::kIsRate);
  state.counters["file_bytes_per_point"] =
      static_cast<double>(std::filesystem::file_size(path)) / points;
}
BENCHMARK(BM_LoadMap)->Arg(10000)->Arg(100000)->Arg(1000000)->Unit(benchmark::kMillisecond);

void BM_LoadForLocalization(benchmark::State& state) {
  const int points = static_cast<int>(state.range(0));
  const std::string& path = MapFile(points);
  size_t bytes = 0;
  for (auto _ : state) {
    const LocalizationMap map(LoadMap(path));
    bytes = map.MemoryBytes();
  }
  state.counters["points_per_s"] = benchmark::Counter(
      static_cast<double>(points) * state.iterations(), benchmark::Counter::kIsRate);
  state.counters["memory_bytes_per_point"] = static_cast<double>(bytes) / points;
}
BENCHMARK(BM_LoadForLocalization)->Arg(100000)->Unit(benchmark::kMillisecond);

void BM_SaveMap(benchmark::State& state) {
  SyntheticMapOptions options;
  options.points = static_cast<int>(state.range(0));
  options.keyframes = options.points / 100;
  Map map = MakeSyntheticMap(options);
  map.metadata.name = "bench";
  TempDir dir("visloc-bench");
  for (auto _ : state) SaveMap(map, dir.File("save.db"));
  state.counters["points_per_s"] = benchmark::Counter(
      static_cast<double>(options.points) * state.iterations(), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_SaveMap)->Arg(100000)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace visloc::mapstore

BENCHMARK_MAIN();
