#include "server/job_spool.h"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "core/image/image_codec.h"

#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"

namespace visloc::server {

namespace fs = std::filesystem;

namespace {

constexpr char kStart[] = "start.pb";
constexpr char kLog[] = "frames.log";
constexpr char kEnd[] = "end";

int64_t SteadyNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// A folder name that is a job id ("12"), or 0.
uint64_t JobIdOf(const std::string& folder_name) {
  if (folder_name.empty() || folder_name.size() > 19 ||
      !std::all_of(folder_name.begin(), folder_name.end(),
                   [](unsigned char c) { return std::isdigit(c) != 0; })) {
    return 0;
  }
  return std::stoull(folder_name);
}

}  // namespace

JobSpool::JobSpool(std::string dir, uint64_t job_id, v1::MappingStart start,
                   const proto::WireLimits& wire)
    : dir_(std::move(dir)),
      job_id_(job_id),
      start_(std::move(start)),
      rig_(proto::FromProto(start_.rig(), wire)) {}

JobSpool::~JobSpool() {
  if (log_) std::fclose(log_);
}

std::unique_ptr<JobSpool> JobSpool::Create(const std::string& spool_dir, uint64_t job_id,
                                           const v1::MappingStart& start,
                                           const proto::WireLimits& wire) {
  const std::string dir = (fs::path(spool_dir) / std::to_string(job_id)).string();
  std::error_code error;
  fs::remove_all(dir, error);  // A folder of an id reused after its spool root was reset.
  if (!fs::create_directories(dir, error)) {
    throw InputError(StrCat("cannot make the mapping spool folder ", dir, ": ", error.message()));
  }
  v1::MappingStart kept = start;
  kept.clear_resume_job_id();
  std::unique_ptr<JobSpool> spool(new JobSpool(dir, job_id, kept, wire));
  WriteFileAtomically((fs::path(dir) / kStart).string(), kept.SerializeAsString());
  spool->OpenLog();
  return spool;
}

std::unique_ptr<JobSpool> JobSpool::Open(const std::string& job_dir,
                                         const proto::WireLimits& wire) {
  const uint64_t id = JobIdOf(fs::path(job_dir).filename().string());
  if (id == 0) throw InputError(StrCat(job_dir, " is not a mapping job's folder"));
  const std::string start_path = (fs::path(job_dir) / kStart).string();
  if (!fs::is_regular_file(start_path)) {
    throw InputError(StrCat("the spool of mapping job ", id, " (", job_dir, ") has no ", kStart));
  }
  v1::MappingStart start;
  if (!start.ParseFromString(ReadFileBytes(start_path)) || start.map_name().empty()) {
    throw InputError(
        StrCat("the spool of mapping job ", id, ": ", start_path, " is not a mapping job's start"));
  }
  std::unique_ptr<JobSpool> spool;
  try {
    spool.reset(new JobSpool(job_dir, id, start, wire));
  } catch (const InputError& e) {
    throw InputError(StrCat("the spool of mapping job ", id, ": ", e.what()));
  }
  spool->ReadLog();
  spool->ended_ = fs::exists(fs::path(job_dir) / kEnd);
  spool->OpenLog();
  return spool;
}

std::vector<uint64_t> JobSpool::JobIds(const std::string& spool_dir) {
  if (!fs::exists(spool_dir)) return {};  // Made by the first job.
  if (!fs::is_directory(spool_dir)) {
    throw InputError(StrCat("the mapping spool ", spool_dir, " is not a folder"));
  }
  std::vector<uint64_t> ids;
  for (const auto& entry : fs::directory_iterator(spool_dir)) {
    const uint64_t id = JobIdOf(entry.path().filename().string());
    if (id != 0 && entry.is_directory()) ids.push_back(id);
  }
  std::sort(ids.begin(), ids.end());
  return ids;
}

// The frames whose line is whole and whose images are there. Frames are logged in order, after
// their images, so the first frame that fails either test ends the run the crash left.
void JobSpool::ReadLog() {
  std::ifstream in(fs::path(dir_) / kLog);
  std::string line;
  while (std::getline(in, line) && !in.eof()) {  // The last line without '\n' was torn.
    long long index = -1, timestamp_ns = 0;
    if (std::sscanf(line.c_str(), "%lld %lld", &index, &timestamp_ns) != 2 ||
        index != static_cast<long long>(timestamps_ns_.size())) {
      break;
    }
    const int i = static_cast<int>(index);
    if (!fs::is_regular_file(Path(i, "left")) || !fs::is_regular_file(Path(i, "right"))) break;
    timestamps_ns_.push_back(timestamp_ns);
  }
  // Rewrite the log to what was kept, so that the frames that follow are numbered after it.
  std::string kept;
  for (size_t i = 0; i < timestamps_ns_.size(); ++i)
    kept += StrCat(i, " ", timestamps_ns_[i], "\n");
  WriteFileAtomically((fs::path(dir_) / kLog).string(), kept);
}

void JobSpool::OpenLog() {
  log_ = std::fopen((fs::path(dir_) / kLog).c_str(), "a");
  if (!log_) throw InputError(StrCat("cannot write the mapping spool's log in ", dir_));
}

std::string JobSpool::name() const {
  return start_.robot_id().empty() ? start_.map_name() : start_.robot_id();
}

std::string JobSpool::Path(int index, const char* side) const {
  return (fs::path(dir_) / StrCat(index, "_", side)).string();  // The bytes tell PNG from JPEG.
}

void JobSpool::Keep(const std::string& encoded, const cv::Mat& decoded,
                    const std::string& path) const {
  bool kept = false;
  if (!encoded.empty()) {
    std::ofstream out(path, std::ios::binary);
    kept =
        static_cast<bool>(out.write(encoded.data(), static_cast<std::streamsize>(encoded.size())));
  } else {
    // Fast PNG: the spool is read back once, and disk is cheaper than the server's time.
    std::string error;
    kept = image::WritePng(path + ".png", decoded, 1, &error) &&
           std::rename((path + ".png").c_str(), path.c_str()) == 0;
  }
  if (!kept) throw InputError(StrCat("cannot keep a frame of the run in ", dir_));
}

void JobSpool::Add(const v1::StereoFrame& frame, const cv::Mat& left, const cv::Mat& right) {
  VISLOC_CHECK(log_ != nullptr, "the spool of job ", job_id_, " was removed");
  const int index = size();
  Keep(frame.left_encoded(), left, Path(index, "left"));
  Keep(frame.right_encoded(), right, Path(index, "right"));
  if (std::fprintf(log_, "%d %lld\n", index, static_cast<long long>(frame.timestamp_ns())) < 0 ||
      std::fflush(log_) != 0) {
    throw InputError(StrCat("cannot write the mapping spool's log in ", dir_));
  }
  const int64_t now_ns = SteadyNowNs();
  if (now_ns - last_sync_ns_ > 1'000'000'000) {
    fdatasync(fileno(log_));
    last_sync_ns_ = now_ns;
  }
  timestamps_ns_.push_back(frame.timestamp_ns());
}

void JobSpool::MarkEnded() {
  if (log_) fsync(fileno(log_));
  WriteFileAtomically((fs::path(dir_) / kEnd).string(), "");
  ended_ = true;
}

void JobSpool::Remove() {
  if (log_) std::fclose(log_);
  log_ = nullptr;
  std::error_code error;
  fs::remove_all(dir_, error);
}

mapping::StereoImages JobSpool::Read(int index) const {
  const auto read = [&](const char* side) {
    std::string error;
    cv::Mat image = image::ReadGrey(Path(index, side), &error);
    if (image.empty()) {
      throw InputError(StrCat("frame ", index, " of mapping job ", job_id_, ": its ", side,
                              " image cannot be read back: ", error));
    }
    return image;
  };
  return {timestamps_ns_[index], read("left"), read("right")};
}

}  // namespace visloc::server
