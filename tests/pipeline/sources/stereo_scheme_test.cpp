// stereo:[PAIRING]//{LEFT}{RIGHT} (pipeline/sources/stereo_scheme.cpp): its parameters set the
// pairing, and each camera is opened by its own URI.
#include <gtest/gtest.h>

#include "pipeline/sources.hpp"
#include "tests/support/fake_gv_camera.hpp"

namespace augrig::pipeline {
namespace {

TEST(StereoScheme, StereoParametersSetThePairing) {
  test::FakeGvCamera fake("127.0.0.1", "SRCS");
  ASSERT_TRUE(fake.running());
  // One camera twice is refused by the camera (one controller), so only the configuration is
  // checked up to opening the second.
  auto o = open_sources(
      "stereo:[tolerance_us=750,mode=trigger_id,clock=shared,queue=3]//{aravis://127.0.0.1}{aravis://"
      "127.0.0.9}");
  ASSERT_FALSE(o);
  EXPECT_NE(o.error().message.find("aravis://127.0.0.9"), std::string::npos) << o.error().message;
}

}  // namespace
}  // namespace augrig::pipeline
