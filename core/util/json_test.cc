#include "core/util/json.h"

#include <gtest/gtest.h>

#include <limits>

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

}  // namespace
}  // namespace visloc
