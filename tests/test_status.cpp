// Status/Result basics.
#include "src/core/status.h"

#include <gtest/gtest.h>

namespace frontier {
namespace {

TEST(Status, OkAndErrorsCarryTheirMessage) {
  EXPECT_TRUE(Status::ok().is_ok());
  const Status s = Status::corruption("store.frontier: page 7: checksum mismatch");
  EXPECT_FALSE(s.is_ok());
  EXPECT_EQ(s.code(), Status::Code::Corruption);
  EXPECT_EQ(s.to_string(), "Corruption: store.frontier: page 7: checksum mismatch");
  Result<int> r = Status::invalid_argument("bad");
  EXPECT_FALSE(r.is_ok());
  EXPECT_EQ(r.status().message(), "bad");
  Result<int> v = 42;
  ASSERT_TRUE(v.is_ok());
  EXPECT_EQ(*v, 42);
}

}  // namespace
}  // namespace frontier
