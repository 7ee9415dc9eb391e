#pragma once
// Read access to a ROS 2 bag's SQLite storage file (.db3, rosbag2_storage_default_plugins'
// sqlite3 plugin): table `topics` (id, name, type, serialization_format) and table `messages`
// (topic_id, timestamp [ns], data: the serialized message). Decoding the data is not SQL's
// business (ros/bag/ros2_bag.h does it); this class only hands out rows.

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "sqlite/sqlite.h"

namespace visloc::bag {

struct Rosbag2Topic {
  int64_t id = 0;
  std::string name;
  std::string type;                  // "sensor_msgs/msg/Image"
  std::string serialization_format;  // "cdr"
  int64_t messages = 0;
};

class Rosbag2Db3 {
 public:
  // Opens read-only. Throws InputError naming the file when it is not SQLite or has no
  // rosbag2 tables.
  explicit Rosbag2Db3(const std::string& path);

  std::vector<Rosbag2Topic> Topics();
  // Calls `visit(topic_id, timestamp_ns, data)` for every message of `topic_ids`, in timestamp
  // order. `data` is valid during the call only.
  void ForEachMessage(const std::vector<int64_t>& topic_ids,
                      const std::function<void(int64_t, int64_t, std::string_view)>& visit);

 private:
  sqlite::Database db_;
};

}  // namespace visloc::bag
