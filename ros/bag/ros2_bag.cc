#include "ros/bag/ros2_bag.h"

#include <algorithm>
#include <filesystem>
#include <map>

#include "core/util/check.h"
#include "ros/bag/rosbag2_db3.h"
#include "ros/bag/ros2_messages.h"

namespace visloc::bag {
namespace {

namespace fs = std::filesystem;

bool HasExtension(const fs::path& path, const char* extension) {
  return path.extension() == extension;
}

std::vector<std::string> StorageFiles(const std::string& path) {
  std::error_code error;
  if (!fs::exists(path, error)) throw NotFoundError(StrCat(path, ": no such bag"));
  if (!fs::is_directory(path, error)) {
    if (HasExtension(path, ".mcap")) {
      throw InputError(StrCat(path, ": MCAP bags are not supported (Debian 12 has no MCAP "
                              "library); convert it with `ros2 bag convert` to sqlite3"));
    }
    return {path};
  }
  std::vector<std::string> db3, mcap;
  for (const fs::directory_entry& entry : fs::directory_iterator(path, error)) {
    if (HasExtension(entry.path(), ".db3")) db3.push_back(entry.path().string());
    if (HasExtension(entry.path(), ".mcap")) mcap.push_back(entry.path().string());
  }
  if (db3.empty() && !mcap.empty()) {
    throw InputError(StrCat(path, ": an MCAP bag; MCAP is not supported (Debian 12 has no MCAP "
                            "library); convert it with `ros2 bag convert` to sqlite3"));
  }
  if (db3.empty()) throw InputError(StrCat(path, ": no .db3 file: not a ROS 2 bag folder"));
  // Split bags: name_0.db3, name_1.db3, ... in the order they were recorded.
  std::sort(db3.begin(), db3.end(), [](const std::string& a, const std::string& b) {
    return a.size() != b.size() ? a.size() < b.size() : a < b;
  });
  return db3;
}

class Ros2Bag : public BagReader {
 public:
  explicit Ros2Bag(std::vector<std::string> files) : files_(std::move(files)) {
    for (const std::string& file : files_) {
      Rosbag2Db3 db(file);  // Refuses a file that is not a bag before any reading.
      for (const Rosbag2Topic& topic : db.Topics()) {
        if (topic.serialization_format != "cdr") {
          throw InputError(StrCat(file, ": topic ", topic.name, " is serialized as '",
                                  topic.serialization_format, "'; only CDR is supported"));
        }
        ros_msg::TopicInfo& info = topics_[topic.name];
        info.name = topic.name;
        info.type = topic.type;
        info.messages += topic.messages;
      }
    }
  }

  std::vector<ros_msg::TopicInfo> Topics() override {
    std::vector<ros_msg::TopicInfo> topics;
    for (const auto& [name, info] : topics_) topics.push_back(info);
    return topics;
  }

  void Read(const std::vector<std::string>& wanted,
            const std::function<void(const ros_msg::BagMessage&)>& visit) override {
    for (const std::string& file : files_) {
      Rosbag2Db3 db(file);
      std::map<int64_t, std::pair<std::string, std::string>> by_id;  // id -> (name, type)
      std::vector<int64_t> ids;
      for (const Rosbag2Topic& topic : db.Topics()) {
        if (std::find(wanted.begin(), wanted.end(), topic.name) == wanted.end()) continue;
        by_id[topic.id] = {topic.name, ros_msg::NormalizeTypeName(topic.type)};
        ids.push_back(topic.id);
      }
      db.ForEachMessage(ids, [&](int64_t topic_id, int64_t timestamp_ns, std::string_view data) {
        const auto& [name, type] = by_id.at(topic_id);
        ros_msg::BagMessage message{name, timestamp_ns, ros_msg::UnknownMessage{}};
        try {
          message.message = DecodeRos2Message(type, data);
        } catch (const InputError& e) {
          throw InputError(StrCat(file, ": ", name, " message recorded at ",
                                  ros_msg::StampText(timestamp_ns), " s: ", e.what()));
        }
        visit(message);
      });
    }
  }

 private:
  std::vector<std::string> files_;
  std::map<std::string, ros_msg::TopicInfo> topics_;
};

}  // namespace

std::unique_ptr<BagReader> OpenRos2Bag(const std::string& path) {
  return std::make_unique<Ros2Bag>(StorageFiles(path));
}

}  // namespace visloc::bag
