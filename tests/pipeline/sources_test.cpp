// Sources by URI in general (pipeline/sources.cpp): per-camera URIs composed into stereo://,
// unknown schemes and parameters. Each scheme's own tests: tests/pipeline/sources/SCHEME_scheme_test.cpp.
#include "pipeline/sources.hpp"

#include <gtest/gtest.h>

#include "tests/support/fake_gv_camera.hpp"

namespace augrig::pipeline {
namespace {

TEST(Sources, PerCameraUrisComposeIntoAStereoSource) {
  std::string why;
  if (!test::ensure_loopback_address("127.0.0.2", &why)) GTEST_SKIP() << why;
  test::FakeGvCamera left("127.0.0.1", "SRCL"), right("127.0.0.2", "SRCR");
  ASSERT_TRUE(left.running());
  ASSERT_TRUE(right.running());
  auto o = open_sources("aravis://127.0.0.1?roi=0,0,64,48&fps=30", "aravis://SRCR?roi=0,0,64,48&fps=30");
  ASSERT_TRUE(o) << o.error().message;
  EXPECT_TRUE(o->live);
  ASSERT_EQ(o->sources.size(), 2u);
  EXPECT_EQ(o->options.pairing.mode, PairingMode::kTimestamp);
  EXPECT_EQ(o->options.pairing.tolerance_ns, 2'000'000);
  EXPECT_FALSE(o->options.pairing.device_clock_shared) << "two cameras, two clocks";
  EXPECT_TRUE(o->options.pairing.clock_offsets.has_value());
  // Two free-running cameras 30 fps apart in phase: pairs come out once the clocks are related.
  o->options.pairing.tolerance_ns = 17'000'000;
  auto stereo = start_stereo(std::move(*o));
  ASSERT_TRUE(stereo) << stereo.error().message;
  int pairs = 0;
  for (int i = 0; i < 100 && pairs < 5; ++i) {
    StereoFrame f;
    auto r = (*stereo)->read(f, std::chrono::milliseconds(100));
    ASSERT_TRUE(r) << r.error().message;
    if (*r == ReadStatus::kFrame) {
      ++pairs;
      EXPECT_EQ(f.left.image.width(), 64);
      EXPECT_EQ(f.right.camera, CameraId::kRight);
    }
  }
  EXPECT_EQ(pairs, 5);
  EXPECT_EQ((*stereo)->stats().clocks.size(), 2u) << "each camera's clock is estimated";
}

TEST(Sources, UnknownSchemesAndParametersAreErrors) {
  for (const char* uri : {"ftp://x", "sim://demo?speed=2", "replay:///no/such/dir",
                          "stereo://{sim://demo}{sim://demo}", "v4l2:///dev/video99?format=TOOLONG",
                          // Out of range or not finite: each would overflow a conversion to ns or to int.
                          "stereo:[tolerance_us=1e300]//{aravis://127.0.0.1}{aravis://127.0.0.2}",
                          "stereo:[tolerance_us=nan]//{aravis://127.0.0.1}{aravis://127.0.0.2}",
                          "stereo:[queue=99999999999]//{aravis://127.0.0.1}{aravis://127.0.0.2}",
                          "stereo://{v4l2:///dev/video99?width=99999999999}{v4l2:///dev/video98}",
                          "stereo://{v4l2:///dev/video99?exposure_us=1e300}{v4l2:///dev/video98}",
                          "sim://demo?rate=inf", "sim://demo?every=99999999999", "replay:///tmp?rate=nan"}) {
    auto o = open_sources(uri);
    ASSERT_FALSE(o) << uri;
    EXPECT_FALSE(o.error().message.empty());
    if (std::string(uri).find("=") != std::string::npos &&
        std::string(uri).find("TOOLONG") == std::string::npos) {
      EXPECT_NE(o.error().message.find("expected"), std::string::npos) << o.error().message;
    }
  }
}

}  // namespace
}  // namespace augrig::pipeline
