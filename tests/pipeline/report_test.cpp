// The run's summary: every frame read is in a pair or a ledger row, and the line says so in
// numbers that add up; the drops by stage, the stages' times, the live view's clients.
#include "pipeline/report.hpp"

#include <sstream>

#include <gtest/gtest.h>

#include "pipeline/pipeline.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::pipeline {
namespace {

TEST(Report, FramesReadAddUpAndEachStageIsNamed) {
  auto opened = open_sources("sim://" + test::data_path("scenarios/short_approach.yaml") + "?rate=0&every=3");
  ASSERT_TRUE(opened) << opened.error().message;
  PipelineParts parts;
  parts.source = std::move(start_stereo(std::move(*opened)).value());
  PipelineReport r;
  r.pairs = 10;
  r.failed_pairs = 1;
  r.skipped_no_pose = 2;
  r.wall_s = 2.0;
  r.source.frames[0] = 27;  // 2 x 13 pairs read + 1 unpaired
  r.source.frames[1] = 26;
  r.source.pairing.unpaired_left = 1;
  r.stage_augment.add(12'000'000);
  r.stage_pose.add(1'000'000);
  r.stage_sinks.add(3'000'000);
  net::ServeStats serve;
  serve.clients_ever = 2;
  serve.messages_sent = 40;
  r.serve = serve;
  std::ostringstream out;
  print_report(r, parts, out);
  const std::string s = out.str();
  EXPECT_NE(s.find("run: 10 stereo frames augmented in 2.0 s (5.0/s"), std::string::npos) << s;
  EXPECT_NE(
      s.find("frames read: left 27, right 26 = 2 x 13 pairs + 1 unpaired + 0 dropped from full queues + 0 "
             "pending at the stop"),
      std::string::npos)
      << s;
  EXPECT_NE(s.find("pairs read but not augmented: 2 without a pose"), std::string::npos) << s;
  EXPECT_NE(s.find("processing 2 (queue 0, failed 1 pairs"), std::string::npos) << s;
  EXPECT_NE(s.find("stages per pair, p50 / p99 ms: pose 1.0 / 1.0, augment 12.0 / 12.0, sinks 3.0 / 3.0"),
            std::string::npos)
      << s;
  EXPECT_NE(s.find("2 client(s), 40 messages sent"), std::string::npos) << s;
}

}  // namespace
}  // namespace augrig::pipeline
