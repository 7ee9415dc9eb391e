#include "core/util/json.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <limits>
#include <string>

namespace visloc {
namespace {

TEST(JsonWriterTest, NestedObjectsArraysAndEscaping) {
  JsonWriter json;
  json.BeginObject()
      .Field("name", "a \"map\"\n")
      .Field("count", 3)
      .Field("ok", true)
      .Key("values")
      .BeginArray()
      .Value(0.5)
      .Value(std::numeric_limits<double>::quiet_NaN())
      .EndArray()
      .Key("empty")
      .BeginObject()
      .EndObject()
      .EndObject();
  EXPECT_EQ(json.str(),
            R"({"name":"a \"map\"\n","count":3,"ok":true,"values":[0.5,null],"empty":{}})");
}

// Numbers are written as printf's "%.9g" writes them: what clients (the page, scripts) parse.
TEST(JsonWriterTest, NumbersAreWrittenAsPrintfWritesThemToNineDigits) {
  for (const double value :
       {0.0, -0.0, 1.0, -2.5, 0.1, 1.0 / 3.0, 123456789.0, 1234567890123.0, 1e-7, -4.2e-12,
        6.02214076e23, 0.001, 12.345, -0.0005, std::numeric_limits<double>::max(),
        std::numeric_limits<double>::denorm_min()}) {
    char expected[32];
    std::snprintf(expected, sizeof(expected), "%.9g", value);
    JsonWriter json;
    json.Value(value);
    EXPECT_EQ(json.str(), std::string(expected)) << value;
  }
}

}  // namespace
}  // namespace visloc
