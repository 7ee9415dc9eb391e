#include "ros/bag/rosbag2_db3.h"

#include "core/util/check.h"

namespace visloc::bag {

Rosbag2Db3::Rosbag2Db3(const std::string& path) : db_(sqlite::Database::OpenReadOnly(path)) {
  if (!db_.HasTable("topics") || !db_.HasTable("messages")) {
    throw InputError(StrCat(path, ": not a ROS 2 bag (no 'topics' and 'messages' tables)"));
  }
}

std::vector<Rosbag2Topic> Rosbag2Db3::Topics() {
  sqlite::Statement select = db_.Prepare(
      "SELECT t.id, t.name, t.type, t.serialization_format, "
      "(SELECT COUNT(*) FROM messages m WHERE m.topic_id = t.id) FROM topics t ORDER BY t.id");
  std::vector<Rosbag2Topic> topics;
  while (select.Step()) {
    topics.push_back({select.ColumnInt64(0), select.ColumnText(1), select.ColumnText(2),
                      select.ColumnText(3), select.ColumnInt64(4)});
  }
  return topics;
}

void Rosbag2Db3::ForEachMessage(
    const std::vector<int64_t>& topic_ids,
    const std::function<void(int64_t, int64_t, std::string_view)>& visit) {
  if (topic_ids.empty()) return;
  std::string placeholders;
  for (size_t i = 0; i < topic_ids.size(); ++i) placeholders += i ? ",?" : "?";
  sqlite::Statement select =
      db_.Prepare("SELECT topic_id, timestamp, data FROM messages WHERE topic_id IN (" +
                  placeholders + ") ORDER BY timestamp, id");
  for (size_t i = 0; i < topic_ids.size(); ++i) select.Bind(static_cast<int>(i + 1), topic_ids[i]);
  while (select.Step()) {
    visit(select.ColumnInt64(0), select.ColumnInt64(1), select.ColumnBlob(2));
  }
}

}  // namespace visloc::bag
