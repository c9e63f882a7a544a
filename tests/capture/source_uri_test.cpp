#include "capture/source_uri.hpp"

#include <gtest/gtest.h>

namespace augrig {
namespace {

TEST(SourceUri, SplitsSchemeTargetAndParameters) {
  auto u = parse_source_uri("aravis://192.168.1.20?format=BayerRG8&fps=30&roi=0,0,1280,960");
  ASSERT_TRUE(u) << u.error().message;
  EXPECT_EQ(u->scheme, "aravis");
  EXPECT_EQ(u->target, "192.168.1.20");
  EXPECT_EQ(u->get("format"), "BayerRG8");
  EXPECT_EQ(u->get("roi"), "0,0,1280,960");
  EXPECT_DOUBLE_EQ(*u->get_number("fps", 0), 30.0);
  EXPECT_EQ(u->get("absent", "dflt"), "dflt");

  u = parse_source_uri("v4l2:///dev/video2");
  ASSERT_TRUE(u);
  EXPECT_EQ(u->scheme, "v4l2");
  EXPECT_EQ(u->target, "/dev/video2");
  EXPECT_TRUE(u->params.empty());

  u = parse_source_uri("replay:///data/flight 7/rec?rate=fast");
  ASSERT_TRUE(u);
  EXPECT_EQ(u->target, "/data/flight 7/rec");
  EXPECT_EQ(u->get("rate"), "fast");
}

TEST(SourceUri, StereoHoldsTwoCameraUris) {
  auto u = parse_source_uri(
      "stereo:[tolerance_us=500,mode=trigger_id]//{aravis://127.0.0.1?fps=30&format=BayerRG8}{aravis://"
      "GV02}");
  ASSERT_TRUE(u) << u.error().message;
  EXPECT_EQ(u->scheme, "stereo");
  EXPECT_EQ(u->get("tolerance_us"), "500");
  EXPECT_EQ(u->get("mode"), "trigger_id");
  ASSERT_EQ(u->children.size(), 2u);
  EXPECT_EQ(u->children[0].target, "127.0.0.1");
  EXPECT_EQ(u->children[0].get("format"), "BayerRG8");
  EXPECT_EQ(u->children[1].text, "aravis://GV02");

  u = parse_source_uri("stereo://{v4l2:///dev/video0}{v4l2:///dev/video1}");
  ASSERT_TRUE(u) << u.error().message;
  EXPECT_TRUE(u->params.empty());
  EXPECT_EQ(u->children[1].target, "/dev/video1");
}

TEST(SourceUri, BadUrisSayWhatWasExpected) {
  struct Case {
    const char* uri;
    const char* message;
  };
  for (const Case c :
       {Case{"camera0", "expected scheme://target"}, Case{"aravis://", "expected a target after aravis://"},
        Case{"aravis://x?fps", ""},  // a bare key means "=1": accepted
        Case{"aravis://x?=3", "expected key=value"}, Case{"aravis://x?a=1&a=2", "parameter 'a' given twice"},
        Case{"stereo:[tolerance_us=5//{a://b}{c://d}", "expected ']'"},
        Case{"stereo:{a://b}{c://d}", "expected stereo:[params]//{left URI}{right URI}"},
        Case{"stereo://{a://b}", "expected '{' to open a camera URI"},
        Case{"stereo://{a://b}{c://d", "unbalanced '{'"},
        Case{"stereo://{a://b}{c://d}x", "unexpected text after"},
        Case{"stereo://{stereo://{a://b}{c://d}}{c://d}", "cannot contain another"}}) {
    auto u = parse_source_uri(c.uri);
    if (std::string(c.message).empty()) {
      EXPECT_TRUE(u) << c.uri;
      continue;
    }
    ASSERT_FALSE(u) << c.uri;
    EXPECT_NE(u.error().message.find(std::string("source URI '")), std::string::npos) << u.error().message;
    EXPECT_NE(u.error().message.find(c.message), std::string::npos) << c.uri << " -> " << u.error().message;
  }
}

TEST(SourceUri, ParameterValuesAreChecked) {
  auto u = parse_source_uri("aravis://x?fps=thirty&buffers=8.5&gain=2");
  ASSERT_TRUE(u);
  auto fps = u->get_number("fps", 0);
  ASSERT_FALSE(fps);
  EXPECT_NE(fps.error().message.find("fps: expected a number in"), std::string::npos);
  EXPECT_NE(fps.error().message.find("got 'thirty'"), std::string::npos);
  auto b = u->get_integer("buffers", 0);
  ASSERT_FALSE(b);
  EXPECT_NE(b.error().message.find("got '8.5'"), std::string::npos);
  Status s = u->check_known({"fps", "buffers"});
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("unknown parameter gain for aravis://; expected fps, buffers"),
            std::string::npos)
      << s.error().message;
  EXPECT_TRUE(u->check_known({"fps", "buffers", "gain"}));
}

// strtod reads nan, inf and 1e999: none of them is a setting (a tolerance of 1e300 us overflowed
// the conversion to nanoseconds). Numbers outside the caller's range name the range.
TEST(SourceUri, NumbersMustBeFiniteAndInRange) {
  for (const char* v : {"nan", "inf", "-inf", "1e999", "1e300"}) {
    auto u = parse_source_uri(std::string("stereo:[tolerance_us=") + v + "]//{sim://a}{sim://b}");
    ASSERT_TRUE(u) << v;
    auto t = u->get_number("tolerance_us", 0, 0, 1e7);
    ASSERT_FALSE(t) << v;
    EXPECT_NE(t.error().message.find("tolerance_us: expected a number in [0, 10000000], got '" +
                                     std::string(v) + "'"),
              std::string::npos)
        << t.error().message;
  }
  auto u = parse_source_uri("v4l2:///dev/video0?width=99999999999&buffers=0");
  ASSERT_TRUE(u);
  auto w = u->get_integer("width", 0, 0, 32768);
  ASSERT_FALSE(w);
  EXPECT_NE(w.error().message.find("width: expected an integer in [0, 32768], got '99999999999'"),
            std::string::npos);
  EXPECT_FALSE(u->get_integer("buffers", 4, 1, 64));
  EXPECT_EQ(*u->get_integer("absent", 4, 1, 64), 4);
}

}  // namespace
}  // namespace augrig
