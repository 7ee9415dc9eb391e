#include "server/auth.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>

#include "core/util/check.h"
#include "core/util/temp_dir.h"
#include "server/rpc.h"

namespace visloc::server {
namespace {

using Outcome = AuthDecision::Outcome;

TokenAuth TwoTokens(const TempDir& dir) {
  std::ofstream(dir.File("tokens")) << "# robots and one admin\n"
                                    << "robot-token-0123456789 localize\n"
                                    << "admin-token-0123456789 admin\n";
  return TokenAuth::FromFile(dir.File("tokens"));
}

// The roles are the transport's business no more: a token alone says what its holder may do.
TEST(TokenAuthTest, RoleOfAToken) {
  const TempDir dir("visloc_auth_test");
  const TokenAuth auth = TwoTokens(dir);
  EXPECT_EQ(auth.RoleOf("robot-token-0123456789"), Role::kLocalize);
  EXPECT_EQ(auth.RoleOf("admin-token-0123456789"), Role::kAdmin);
  EXPECT_EQ(auth.RoleOf("nobody-token-01234567"), std::nullopt);
  EXPECT_EQ(auth.RoleOf(""), std::nullopt);
}

TEST(TokenAuthTest, AuthorizeDecidesFromTheHeaderValueAndSaysWhy) {
  const TempDir dir("visloc_auth_test");
  const TokenAuth auth = TwoTokens(dir);
  EXPECT_TRUE(auth.Authorize("Bearer robot-token-0123456789", Role::kLocalize).allowed());
  EXPECT_TRUE(auth.Authorize("Bearer admin-token-0123456789", Role::kLocalize).allowed());
  EXPECT_TRUE(auth.Authorize("Bearer admin-token-0123456789", Role::kAdmin).allowed());

  const AuthDecision weak = auth.Authorize("Bearer robot-token-0123456789", Role::kAdmin);
  EXPECT_EQ(weak.outcome, Outcome::kPermissionDenied);
  EXPECT_THAT(weak.message, ::testing::HasSubstr("may localize but not manage maps"));

  const AuthDecision missing = auth.Authorize(std::nullopt, Role::kLocalize);
  EXPECT_EQ(missing.outcome, Outcome::kUnauthenticated);
  EXPECT_THAT(missing.message, ::testing::HasSubstr("--token"));
  EXPECT_EQ(auth.Authorize("robot-token-0123456789", Role::kLocalize).outcome,
            Outcome::kUnauthenticated);  // No "Bearer ".
  EXPECT_EQ(auth.Authorize("Bearer wrong", Role::kLocalize).outcome, Outcome::kUnauthenticated);

  // Without a tokens file everything is allowed.
  EXPECT_TRUE(TokenAuth().Authorize(std::nullopt, Role::kAdmin).allowed());
}

TEST(TokenAuthTest, DecisionsBecomeTheGrpcCodes) {
  EXPECT_EQ(ToStatus({Outcome::kAllowed, ""}).error_code(), grpc::StatusCode::OK);
  EXPECT_EQ(ToStatus({Outcome::kUnauthenticated, "x"}).error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(ToStatus({Outcome::kPermissionDenied, "y"}).error_message(), "y");
}

TEST(TokenAuthTest, MalformedTokenFilesNameTheLine) {
  const TempDir dir("visloc_auth_test");
  std::ofstream(dir.File("short")) << "short localize\n";
  EXPECT_THROW(TokenAuth::FromFile(dir.File("short")), InputError);
  std::ofstream(dir.File("role")) << "long-enough-token-0123 superuser\n";
  try {
    TokenAuth::FromFile(dir.File("role"));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("role:1"));
  }
}

}  // namespace
}  // namespace visloc::server
