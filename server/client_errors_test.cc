#include "server/client_errors.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/util/check.h"
#include "core/util/temp_dir.h"

namespace visloc::server {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

TEST(ClientErrorsTest, ServerPathsBecomeWhatTheyMeanToAClient) {
  TempDir maps("visloc-client-errors");
  EXPECT_EQ(
      RedactForClient(maps.File(".lab.db.tmp-4242-7") + ": not a visloc map (no 'meta' table)"),
      "map 'lab' (staged upload): not a visloc map (no 'meta' table)");
  EXPECT_EQ(RedactForClient("no map named 'x' in " + maps.path()),
            "no map named 'x' in the maps folder");
  EXPECT_EQ(RedactForClient("cannot open '" + maps.File("lab.db") + "'"),
            "cannot open 'map 'lab''");
  EXPECT_EQ(RedactForClient("/etc/passwd, twice: /etc/passwd"),
            "a server file, twice: a server file");
  EXPECT_EQ(RedactForClient("image is 320x240 but the session camera is 640x480"),
            "image is 320x240 but the session camera is 640x480");
  EXPECT_EQ(RedactForClient("frame 3 / 4 of 1/2 s"), "frame 3 / 4 of 1/2 s");
}

TEST(ClientErrorsTest, UnexpectedExceptionsGiveOnlyAReference) {
  try {
    VISLOC_CHECK(1 + 1 == 3, "visibility k ", 4000000000u, " overflows");
  } catch (const std::exception& e) {
    const grpc::Status status = StatusFromException(e, "test");
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INTERNAL);
    EXPECT_THAT(status.error_message(), HasSubstr("internal server error (reference "));
    EXPECT_THAT(status.error_message(), Not(HasSubstr(".cc")));
    EXPECT_THAT(status.error_message(), Not(HasSubstr("overflows")));
  }
  const grpc::Status not_found = StatusFromException(NotFoundError("no map named 'x'"), "test");
  EXPECT_EQ(not_found.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(not_found.error_message(), "no map named 'x'");
  const grpc::Status invalid = StatusFromException(InputError("camera.fx is 0"), "test");
  EXPECT_EQ(invalid.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
}

}  // namespace
}  // namespace visloc::server
