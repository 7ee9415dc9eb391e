// Fuzz target: the dataset readers, on files a user points `visloc map build`, `localize` or
// `stream` at. The first byte picks the reader; the rest is split into files (fuzz_input.h):
//   0: a TUM trajectory (the whole rest)
//   1: an EuRoC folder: cam0/data.csv, cam0/sensor.yaml, cam1/data.csv, cam1/sensor.yaml,
//      imu0/data.csv, odometry0/data.csv, state_groundtruth_estimate0/data.csv
//   2: a KITTI sequence: calib.txt, times.txt, poses.txt, and image_0/ with two (empty) images
// Bad files must end in InputError naming the file (and line), never a crash.

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/util/check.h"
#include "core/util/temp_dir.h"
#include "dataset/dataset.h"
#include "dataset/tum.h"
#include "fuzz/fuzz_input.h"

namespace fs = std::filesystem;

namespace {

void WriteFile(const fs::path& path, const std::string& bytes) {
  fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const visloc::TempDir scratch("visloc-dataset-fuzz");
  visloc::fuzz::FuzzInput input(data, size);
  const int kind = input.Byte() % 3;
  const fs::path dir = fs::path(scratch.path()) / "case";
  fs::remove_all(dir);
  try {
    if (kind == 0) {
      WriteFile(dir / "trajectory.tum", input.Rest());
      visloc::ReadTum((dir / "trajectory.tum").string());
    } else if (kind == 1) {
      for (const char* file :
           {"cam0/data.csv", "cam0/sensor.yaml", "cam1/data.csv", "cam1/sensor.yaml",
            "imu0/data.csv", "odometry0/data.csv", "state_groundtruth_estimate0/data.csv"}) {
        const std::string bytes = input.Chunk();
        if (!bytes.empty()) WriteFile(dir / "mav0" / file, bytes);
      }
      fs::create_directories(dir / "mav0" / "cam0" / "data");
      visloc::ReadDataset(dir.string(), visloc::DatasetFormat::kEuroc);
    } else {
      for (const char* file : {"calib.txt", "times.txt", "poses.txt"}) {
        WriteFile(dir / file, input.Chunk());
      }
      WriteFile(dir / "image_0" / "000000.png", "");
      WriteFile(dir / "image_0" / "000001.png", "");
      visloc::ReadDataset(dir.string(), visloc::DatasetFormat::kKitti);
    }
  } catch (const visloc::InputError&) {
    // Refused with a message.
  }
  return 0;
}
