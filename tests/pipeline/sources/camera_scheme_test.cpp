// aravis:// and v4l2:// (pipeline/sources/camera_scheme.cpp): a stereo rig's cameras; alone, one
// camera is refused.
#include <gtest/gtest.h>

#include "pipeline/sources.hpp"

namespace augrig::pipeline {
namespace {

TEST(CameraScheme, OneCameraIsNotAStereoRig) {
  auto ok = open_sources("aravis://127.0.0.1?roi=0,0,64,48", "");
  ASSERT_FALSE(ok) << "a single camera is not a rig";
  EXPECT_NE(ok.error().message.find("one camera is not a stereo rig"), std::string::npos);
}

// Nothing in a command sends software triggers: such a camera is refused before anything is
// opened, rather than waiting for a frame forever.
TEST(CameraScheme, SoftwareTriggerIsRefused) {
  auto o = open_sources("stereo://{aravis://127.0.0.1?trigger=software}{aravis://127.0.0.2}");
  ASSERT_FALSE(o);
  EXPECT_NE(o.error().message.find("trigger=software"), std::string::npos) << o.error().message;
  EXPECT_NE(o.error().message.find("expected free, or LineN"), std::string::npos) << o.error().message;
}

}  // namespace
}  // namespace augrig::pipeline
