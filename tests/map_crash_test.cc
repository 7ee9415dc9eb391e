// Kills a real writer process (SIGKILL) at moments spread over a map write and checks that the
// map file always holds a complete map: the previous one or the new one, never a broken one.

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <thread>

#include "core/map/synthetic_map.h"
#include "core/util/temp_dir.h"
#include "core/util/timer.h"
#include "mapstore/map_store.h"
#include "tests/support/process.h"

namespace visloc {
namespace {

namespace fs = std::filesystem;
constexpr int kPoints = 120000;

Map ExpectedMap(uint64_t seed) {
  SyntheticMapOptions options;
  options.points = kPoints;
  options.keyframes = kPoints / 100;
  options.seed = seed;
  Map map = MakeSyntheticMap(options);
  map.metadata.name = "crash";
  return map;
}

int CountTemporaries(const std::string& dir) {
  int count = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.path().filename().string().find(".tmp-") != std::string::npos) ++count;
  }
  return count;
}

// Waits until the writer has built its map and starts writing (it creates PATH.ready).
bool WaitUntilWriting(const std::string& path) {
  for (int i = 0; i < 20000; ++i) {
    if (fs::exists(path + ".ready")) return true;
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  return false;
}

std::vector<std::string> WriterArgs(const std::string& path, uint64_t seed) {
  return {VISLOC_WRITER_PATH, path, std::to_string(kPoints), std::to_string(seed)};
}

TEST(MapCrashTest, KilledWriterLeavesTheOldMapOrTheNewOne) {
  TempDir dir;
  const std::string path = dir.File("map.db");
  mapstore::SaveMap(ExpectedMap(1), path);
  // How long one complete write takes, so the kills can be spread over it.
  const int calibration = testing::SpawnProcess(WriterArgs(path, 2));
  ASSERT_TRUE(WaitUntilWriting(path));
  Timer timer;
  ASSERT_EQ(testing::WaitProcess(calibration), 0);
  const double write_ms = timer.ElapsedMs();
  fs::remove(path + ".ready");
  uint64_t current_seed = 2;
  ASSERT_TRUE(MapsEqual(mapstore::LoadMap(path), ExpectedMap(current_seed)));

  // Kill moments cycle over 5-80% of the calibrated write time; under load writes get slower,
  // so kills land earlier in them. Keep going until enough kills landed mid-write.
  constexpr int kWanted = 8, kMaxAttempts = 30;
  int killed_mid_write = 0, old_survived = 0, new_landed = 0;
  for (int i = 0; i < kMaxAttempts && killed_mid_write < kWanted; ++i) {
    const uint64_t new_seed = 10 + i;
    const int pid = testing::SpawnProcess(WriterArgs(path, new_seed));
    ASSERT_TRUE(WaitUntilWriting(path));
    const double fraction = 0.05 + 0.75 * (i % 8) / 7.0;
    std::this_thread::sleep_for(std::chrono::duration<double, std::milli>(write_ms * fraction));
    const int exit_code = testing::KillProcess(pid, SIGKILL);
    if (exit_code == 128 + SIGKILL && CountTemporaries(dir.path()) > 0) ++killed_mid_write;
    const Map loaded = mapstore::LoadMap(path);  // must not throw: never a broken map
    if (MapsEqual(loaded, ExpectedMap(current_seed))) {
      ++old_survived;
    } else {
      ASSERT_TRUE(MapsEqual(loaded, ExpectedMap(new_seed))) << "kill " << i << " left a third map";
      current_seed = new_seed;
      ++new_landed;
    }
    for (const auto& entry : fs::directory_iterator(dir.path())) {
      if (entry.path() != path) fs::remove(entry.path());  // what a restart's cleanup does
    }
  }
  EXPECT_GE(killed_mid_write, kWanted) << "the kills did not land during writes";
  RecordProperty("write_ms", static_cast<int>(write_ms));
  RecordProperty("killed_mid_write", killed_mid_write);
  std::printf(
      "write %.0f ms; %d kills mid-write: old map intact %d times, new map landed %d times\n",
      write_ms, killed_mid_write, old_survived, new_landed);
}

}  // namespace
}  // namespace visloc
