#include "core/util/json.h"

#include <charconv>
#include <cmath>
#include <cstdio>

#include "core/util/check.h"

namespace visloc {

std::string JsonEscape(const std::string& text) {
  std::string out = "\"";
  for (const char c : text) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\r':
        out += "\\r";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buffer[8];
          std::snprintf(buffer, sizeof(buffer), "\\u%04x", c);
          out += buffer;
        } else {
          out += c;
        }
    }
  }
  return out + "\"";
}

void JsonWriter::BeforeValue() {
  if (after_key_) {
    after_key_ = false;
    return;
  }
  if (!first_in_scope_.empty()) {
    if (!first_in_scope_.back()) out_ += ",";
    first_in_scope_.back() = false;
  }
}

JsonWriter& JsonWriter::BeginObject() {
  BeforeValue();
  out_ += "{";
  first_in_scope_.push_back(true);
  return *this;
}
JsonWriter& JsonWriter::EndObject() {
  VISLOC_CHECK(!first_in_scope_.empty(), "EndObject without BeginObject");
  first_in_scope_.pop_back();
  out_ += "}";
  return *this;
}
JsonWriter& JsonWriter::BeginArray() {
  BeforeValue();
  out_ += "[";
  first_in_scope_.push_back(true);
  return *this;
}
JsonWriter& JsonWriter::EndArray() {
  VISLOC_CHECK(!first_in_scope_.empty(), "EndArray without BeginArray");
  first_in_scope_.pop_back();
  out_ += "]";
  return *this;
}
JsonWriter& JsonWriter::Key(const std::string& key) {
  BeforeValue();
  out_ += JsonEscape(key) + ":";
  after_key_ = true;
  return *this;
}
JsonWriter& JsonWriter::Value(const std::string& value) {
  BeforeValue();
  out_ += JsonEscape(value);
  return *this;
}
JsonWriter& JsonWriter::Value(double value) {
  BeforeValue();
  if (!std::isfinite(value)) {
    out_ += "null";
    return *this;
  }
  // printf's "%.9g" text (the standard defines to_chars's general format so), written without
  // parsing a format string: the operator page's map views are tens of thousands of numbers,
  // and snprintf was four fifths of their cost.
  char buffer[32];
  const std::to_chars_result written =
      std::to_chars(buffer, buffer + sizeof(buffer), value, std::chars_format::general, 9);
  out_.append(buffer, written.ptr);
  return *this;
}
JsonWriter& JsonWriter::Value(int64_t value) {
  BeforeValue();
  out_ += std::to_string(value);
  return *this;
}
JsonWriter& JsonWriter::Value(bool value) {
  BeforeValue();
  out_ += value ? "true" : "false";
  return *this;
}
JsonWriter& JsonWriter::Null() {
  BeforeValue();
  out_ += "null";
  return *this;
}

}  // namespace visloc
