#pragma once
// Test-only: writes a ROS 2 sqlite3 bag (the rosbag2 schema the reader expects) from CDR
// messages, for tests and fuzz seeds without ROS 2 installed.

#include <map>
#include <string>

#include "sqlite/sqlite.h"

namespace visloc::bag::testing {

class Ros2BagWriter {
 public:
  explicit Ros2BagWriter(const std::string& db3_path)
      : db_(sqlite::Database::OpenForWriting(db3_path)) {
    db_.Exec(
        "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, "
        "serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);"
        "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, "
        "timestamp INTEGER NOT NULL, data BLOB NOT NULL);");
  }
  void Write(const std::string& topic, const std::string& type, int64_t timestamp_ns,
             const std::string& cdr) {
    auto [it, added] = ids_.emplace(topic, static_cast<int64_t>(ids_.size() + 1));
    if (added) {
      db_.Prepare("INSERT INTO topics VALUES (?, ?, ?, 'cdr', '')")
          .Bind(1, it->second).Bind(2, topic).Bind(3, type).Run();
    }
    db_.Prepare("INSERT INTO messages(topic_id, timestamp, data) VALUES (?, ?, ?)")
        .Bind(1, it->second).Bind(2, timestamp_ns).BindBlob(3, cdr.data(), cdr.size()).Run();
  }

 private:
  sqlite::Database db_;
  std::map<std::string, int64_t> ids_;
};

}  // namespace visloc::bag::testing
