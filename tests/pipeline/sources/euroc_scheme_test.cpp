// euroc://DIR (pipeline/sources/euroc_scheme.cpp): what its parameters refuse before the dataset is
// opened. Playing datasets: tests/recorder/euroc_source_test.cpp.
#include <gtest/gtest.h>

#include "pipeline/sources.hpp"

namespace augrig::pipeline {
namespace {

TEST(EurocScheme, FromFrameAndSeekExcludeEachOther) {
  auto o = open_sources("euroc:///no/such/dir?from_frame=3&seek_s=1.5");
  ASSERT_FALSE(o);
  EXPECT_EQ(
      o.error().message,
      "source URI 'euroc:///no/such/dir?from_frame=3&seek_s=1.5': from_frame and seek_s exclude each other");
  for (const char* uri : {"euroc:///no/such/dir?from_frame=-1", "euroc:///no/such/dir?seek_s=inf",
                          "euroc:///no/such/dir?tolerance_ns=-5"}) {
    auto bad = open_sources(uri);
    ASSERT_FALSE(bad) << uri;
    EXPECT_NE(bad.error().message.find("expected"), std::string::npos) << bad.error().message;
  }
}

}  // namespace
}  // namespace augrig::pipeline
