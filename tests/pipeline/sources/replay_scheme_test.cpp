// replay://DIR and replay://FILE.mcap (pipeline/sources/replay_scheme.cpp): what its parameters
// refuse before the recording is opened. Playing recordings: tests/recorder/replay_source_test.cpp,
// tests/pipeline/pipeline_test.cpp.
#include <gtest/gtest.h>

#include "pipeline/sources.hpp"

namespace augrig::pipeline {
namespace {

TEST(ReplayScheme, FromFrameAndSeekExcludeEachOther) {
  auto o = open_sources("replay:///no/such/dir?from_frame=3&seek_s=1.5");
  ASSERT_FALSE(o);
  EXPECT_EQ(
      o.error().message,
      "source URI 'replay:///no/such/dir?from_frame=3&seek_s=1.5': from_frame and seek_s exclude each other");
  for (const char* uri : {"replay:///no/such/dir?from_frame=-1", "replay:///no/such/dir?seek_s=nan",
                          "replay:///no/such/dir?late=never", "replay:///no/such/dir?rate=0"}) {
    auto bad = open_sources(uri);
    ASSERT_FALSE(bad) << uri;
    EXPECT_NE(bad.error().message.find("expected"), std::string::npos) << bad.error().message;
  }
  // An MCAP file plays as fast as it is read: pacing it is refused.
  auto mcap = open_sources("replay:///no/such/file.mcap?rate=2");
  ASSERT_FALSE(mcap);
  EXPECT_NE(mcap.error().message.find("pacing needs a recording"), std::string::npos) << mcap.error().message;
}

}  // namespace
}  // namespace augrig::pipeline
