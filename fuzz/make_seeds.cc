// Writes the seed corpus of every fuzz target into OUT/<target>/: valid inputs (and a few
// near-valid ones) from which libFuzzer's mutations start. The committed corpus in
// fuzz/corpus/ is this tool's output; rerun it when an input format changes.
// Usage: make_seeds OUT

#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "core/image/image_codec.h"
#include "core/map/synthetic_map.h"
#include "core/util/check.h"
#include "core/util/temp_dir.h"
#include "core/util/text_file.h"
#include "dataset/euroc.h"
#include "dataset/kitti.h"
#include "dataset/tum.h"
#include "fuzz/fuzz_input.h"
#include "mapstore/checksum.h"
#include "mapstore/map_store.h"
#include "proto/convert.h"
#include "ros/bag/cdr_test_writer.h"

namespace visloc::fuzz {
namespace {

namespace fs = std::filesystem;

cv::Mat Texture(int width, int height) {
  cv::Mat image(height, width, CV_8UC1);
  cv::randu(image, 0, 255);
  cv::GaussianBlur(image, image, cv::Size(), 1.0);
  return image;
}

void Write(const fs::path& dir, const std::string& name, const std::string& bytes) {
  fs::create_directories(dir);
  WriteFileAtomically((dir / name).string(), bytes);
}

std::string Tagged(int tag, const std::string& rest) {
  return std::string(1, static_cast<char>(tag)) + rest;
}

const Camera kCamera(64, 48, 40.0, 40.0, 31.5, 23.5);

v1::Frame RawFrame(int64_t timestamp_ns) {
  const cv::Mat image = Texture(kCamera.width(), kCamera.height());
  v1::Frame frame;
  frame.set_timestamp_ns(timestamp_ns);
  v1::RawImage* raw = frame.mutable_raw();
  raw->set_width(image.cols);
  raw->set_height(image.rows);
  raw->set_stride(static_cast<uint32_t>(image.step[0]));
  raw->set_pixels(image.data, image.step[0] * image.rows);
  return frame;
}

std::vector<uint8_t> Png(const cv::Mat& image) {
  std::vector<uint8_t> png;
  std::string error;
  VISLOC_CHECK(image::EncodePng(image, 1, &png, &error), error);
  return png;
}

void FrameSeeds(const fs::path& out) {
  v1::Frame raw = RawFrame(1000);
  Write(out, "frame_raw", Tagged(0, raw.SerializeAsString()));
  const std::vector<uint8_t> png = Png(Texture(kCamera.width(), kCamera.height()));
  v1::Frame encoded;
  encoded.set_timestamp_ns(2000);
  encoded.set_encoded(std::string(png.begin(), png.end()));
  Write(out, "frame_png", Tagged(0, encoded.SerializeAsString()));
  v1::Frame motion = RawFrame(3000);
  proto::ToProto(Rigid3d(), motion.mutable_odom_from_cam());
  proto::ToProto(Rigid3d(), motion.mutable_map_from_cam_hint());
  v1::ImuSample* imu = motion.add_imu();
  imu->set_timestamp_ns(2900);
  imu->set_gyro_z(0.1);
  Write(out, "frame_motion", Tagged(0, motion.SerializeAsString()));
  v1::SessionStart start;
  start.set_map_name("seed");
  proto::ToProto(kCamera, start.mutable_camera());
  start.mutable_options()->set_visibility_k(5);
  Write(out, "session_start", Tagged(1, start.SerializeAsString()));
  v1::RelocalizeRequest relocalize;
  relocalize.set_encoded_image(std::string(png.begin(), png.end()));
  Write(out, "relocalize", Tagged(2, relocalize.SerializeAsString()));
  LocalizationResult result;
  result.timestamp_ns = 42;
  result.has_pose = true;
  result.status = TrackingStatus::kTracking;
  v1::LocalizeResponse response;
  proto::ToProto(result, 7, &response);
  Write(out, "response", Tagged(3, response.SerializeAsString()));
}

void RpcSeeds(const fs::path& out, const std::string& map_bytes) {
  v1::LocalizeRequest start;
  start.mutable_start()->set_map_name("seed");
  proto::ToProto(kCamera, start.mutable_start()->mutable_camera());
  std::string session;
  AppendChunk(start.SerializeAsString(), &session);
  for (int i = 0; i < 3; ++i) {
    v1::LocalizeRequest frame;
    *frame.mutable_frame() = RawFrame(1000 * (i + 1));
    AppendChunk(frame.SerializeAsString(), &session);
  }
  Write(out, "localize", Tagged(0, session));
  v1::RelocalizeRequest relocalize;
  relocalize.set_map_name("seed");
  *relocalize.mutable_raw_image() = RawFrame(1).raw();
  proto::ToProto(kCamera, relocalize.mutable_camera());
  Write(out, "relocalize", Tagged(1, relocalize.SerializeAsString()));
  Write(out, "list", Tagged(2, ""));
  v1::MapName seed;
  seed.set_name("seed");
  Write(out, "info", Tagged(3, seed.SerializeAsString()));
  std::string upload;
  v1::UploadChunk header;
  header.mutable_header()->set_name("uploaded");
  header.mutable_header()->set_size_bytes(map_bytes.size());
  header.mutable_header()->set_crc32(mapstore::Crc32(map_bytes));
  AppendChunk(header.SerializeAsString(), &upload);
  // Uploads come in 64 KiB chunks from the client; a chunk here holds at most 64 KiB - 1 bytes
  // of serialized message, so the file goes in smaller pieces.
  for (size_t offset = 0; offset < map_bytes.size(); offset += 32768) {
    v1::UploadChunk data;
    data.set_data(map_bytes.substr(offset, 32768));
    AppendChunk(data.SerializeAsString(), &upload);
  }
  Write(out, "upload", Tagged(4, upload));
  Write(out, "download", Tagged(5, seed.SerializeAsString()));
  v1::MapName missing;
  missing.set_name("../seed");
  Write(out, "delete_escaping", Tagged(6, missing.SerializeAsString()));
  v1::RenameMapRequest rename;
  rename.set_from("seed");
  rename.set_to("renamed");
  Write(out, "rename", Tagged(7, rename.SerializeAsString()));
}

void DatasetSeeds(const fs::path& out) {
  const TempDir scratch("visloc-seeds");
  Trajectory trajectory;
  trajectory.push_back({1000000000, Rigid3d()});
  trajectory.push_back({1100000000, Rigid3d(Eigen::Quaterniond::Identity(), {0.1, 0, 0})});
  WriteTum(scratch.File("t.tum"), trajectory);
  Write(out, "tum", Tagged(0, ReadFileBytes(scratch.File("t.tum"))));

  const std::string euroc = scratch.File("euroc");
  CameraInfo left{kCamera, Rigid3d(), 15.0};
  CameraInfo right = left;
  right.body_from_cam = Rigid3d(Eigen::Quaterniond::Identity(), {0.1, 0, 0});
  EurocWriter writer(euroc, left, right);
  for (int i = 0; i < 2; ++i) {
    writer.AddFrame(1000000000 + i * 66666667, Texture(64, 48), Texture(64, 48));
  }
  std::vector<ImuSample> imu(3);
  for (int i = 0; i < 3; ++i) imu[i].timestamp_ns = 1000000000 + i * 5000000;
  writer.Finish(imu, trajectory, trajectory);
  std::string files;
  for (const char* file :
       {"cam0/data.csv", "cam0/sensor.yaml", "cam1/data.csv", "cam1/sensor.yaml", "imu0/data.csv",
        "odometry0/data.csv", "state_groundtruth_estimate0/data.csv"}) {
    const fs::path path = fs::path(euroc) / "mav0" / file;
    AppendChunk(fs::exists(path) ? ReadFileBytes(path.string()) : "", &files);
  }
  Write(out, "euroc", Tagged(1, files));

  const std::string kitti = scratch.File("kitti");
  fs::create_directories(kitti);
  WriteKittiCalibration(kitti, kCamera, 0.1);
  WriteKittiTimesAndPoses(kitti, {0, 100000000}, trajectory);
  files.clear();
  for (const char* file : {"calib.txt", "times.txt", "poses.txt"}) {
    const fs::path path = fs::path(kitti) / file;
    AppendChunk(fs::exists(path) ? ReadFileBytes(path.string()) : "", &files);
  }
  Write(out, "kitti", Tagged(2, files));
}

// One valid message of each type the importer reads, tagged with its type's byte.
void Ros2MessageSeeds(const fs::path& out) {
  const cv::Mat image = Texture(16, 12);
  Write(out, "image", Tagged(0, bag::testing::Ros2Image(1'700'000'000'000'000'000, image, "cam0")));
  const std::vector<uint8_t> png = Png(image);
  Write(out, "compressed",
        Tagged(1, bag::testing::Ros2CompressedImage(5, "png", std::string(png.begin(), png.end()),
                                                    "cam0")));
  Write(out, "camera_info",
        Tagged(2, bag::testing::Ros2CameraInfo(5, 16, 12, 20.0, 8.0, 6.0, {0.01, 0, 0, 0, 0}, 0.1)));
  Write(out, "camera_info_fisheye",
        Tagged(2, bag::testing::Ros2CameraInfo(5, 16, 12, 20.0, 8.0, 6.0, {0.01, 0, 0, 0}, 0.1,
                                               "equidistant")));
  const double xyz[3] = {1, 2, 3}, q[4] = {0, 0, 0, 1};
  Write(out, "odometry", Tagged(4, bag::testing::Ros2Odometry(5, xyz, q)));
}

std::string SmallMapBytes() {
  const TempDir scratch("visloc-seeds");
  SyntheticMapOptions options;
  options.keyframes = 4;
  options.points = 40;
  options.vocabulary_depth = 1;
  Map map = MakeSyntheticMap(options);
  map.metadata.name = "small";
  mapstore::SaveMap(map, scratch.File("small.db"), mapstore::SaveMapOptions{1024});
  return ReadFileBytes(scratch.File("small.db"));
}

}  // namespace
}  // namespace visloc::fuzz

int main(int argc, char** argv) {
  using namespace visloc::fuzz;
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_seeds OUT\n");
    return 2;
  }
  try {
    const fs::path out(argv[1]);
    const std::string map_bytes = SmallMapBytes();
    FrameSeeds(out / "frame");
    RpcSeeds(out / "rpc", map_bytes);
    DatasetSeeds(out / "dataset");
    Write(out / "map", "small.db", map_bytes);
    Ros2MessageSeeds(out / "ros2_message");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "make_seeds: %s\n", e.what());
    return 1;
  }
  return 0;
}
