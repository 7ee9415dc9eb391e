#pragma once
// A minimal streaming JSON writer for `--json` outputs: objects, arrays, strings, numbers and
// booleans, with correct escaping. Non-finite numbers are written as null (JSON has no NaN).

#include <cstdint>
#include <string>
#include <vector>

namespace visloc {

class JsonWriter {
 public:
  JsonWriter& BeginObject();
  JsonWriter& EndObject();
  JsonWriter& BeginArray();
  JsonWriter& EndArray();
  // Inside an object, Key() precedes each value.
  JsonWriter& Key(const std::string& key);
  JsonWriter& Value(const std::string& value);
  JsonWriter& Value(const char* value) { return Value(std::string(value)); }
  JsonWriter& Value(double value);
  JsonWriter& Value(int64_t value);
  JsonWriter& Value(uint64_t value) { return Value(static_cast<int64_t>(value)); }
  JsonWriter& Value(int value) { return Value(static_cast<int64_t>(value)); }
  JsonWriter& Value(bool value);
  JsonWriter& Null();
  // Shorthand for Key(key).Value(value).
  template <typename T>
  JsonWriter& Field(const std::string& key, const T& value) {
    Key(key);
    return Value(value);
  }
  const std::string& str() const { return out_; }

 private:
  void BeforeValue();
  std::string out_;
  std::vector<bool> first_in_scope_;
  bool after_key_ = false;
};

std::string JsonEscape(const std::string& text);

}  // namespace visloc
