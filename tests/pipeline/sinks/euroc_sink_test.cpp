// The EuRoC sink: a run's pairs written as `augrig export` writes the recording of the same run,
// file for file and byte for byte (the export being the oracle: images, data.csv, sensor.yaml,
// poses.csv, stats.csv, phases.csv, frames.csv, the receiver's states); its options; bad arguments
// and a folder that holds an export already are named.
#include <filesystem>
#include <fstream>
#include <map>

#include <gtest/gtest.h>

#include "pipeline/report.hpp"
#include "pipeline/sinks/registry.hpp"
#include "recorder/euroc.hpp"
#include "recorder/recorder.hpp"
#include "tests/support/output_files.hpp"
#include "tests/support/pipeline_parts.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::pipeline {
namespace {

namespace fs = std::filesystem;

const std::string kScenario = "sim://" + test::data_path("scenarios/short_approach.yaml") + "?every=4&rate=0";

TEST(EurocSink, WritesWhatExportWritesFromTheRecordingOfTheSameRun) {
  const std::string out = test::output_dir("euroc_sink_same");
  fs::remove_all(out);
  PipelineParts p = test::pipeline_parts(kScenario);
  p.max_pairs = 5;
  const Rig rig = p.rig;
  recorder::RecordingInfo info;
  info.rig_yaml = rig_to_yaml(rig);
  auto rec = recorder::Recorder::create(out + "/rec", info);
  ASSERT_TRUE(rec) << rec.error().message;
  p.recorder = std::move(*rec);
  p.record_ground_truth = true;
  auto sink = make_sink("euroc:" + out + "/run,no-plot,ground-truth", {p.rig});
  ASSERT_TRUE(sink) << sink.error().message;
  p.sinks.push_back(std::move(*sink));
  Pipeline pipeline(std::move(p));
  std::ostringstream o, e;
  auto report = pipeline.run(o, e);
  ASSERT_TRUE(report) << report.error().message;
  ASSERT_EQ(report->pairs, 5u);
  ASSERT_EQ(report->outputs.size(), 1u);
  EXPECT_NE(report->outputs[0].find("run: 5 stereo frame(s) in the EuRoC layout"), std::string::npos)
      << report->outputs[0];
  EXPECT_FALSE(fs::exists(out + "/run/INCOMPLETE"));

  // The oracle: the recording of the same run, exported (on the frames' own clock: the recording
  // states no link to GPS time).
  auto reader = recorder::RecordingReader::open(out + "/rec");
  ASSERT_TRUE(reader) << reader.error().message;
  recorder::EurocExportOptions eo;
  eo.rig = rig;  // the run's, not its YAML round trip (a rotation's last bits)
  eo.plot = false;
  eo.ground_truth = true;
  eo.threads = 1;
  recorder::EurocExportReport er;
  ASSERT_TRUE(recorder::export_euroc(**reader, out + "/export", eo, er));
  const auto run = test::files_under(out + "/run"), exported = test::files_under(out + "/export");
  ASSERT_EQ(run.size(), exported.size());
  for (const auto& [name, bytes] : exported) {
    ASSERT_TRUE(run.count(name)) << name;
    EXPECT_TRUE(run.at(name) == bytes) << name;
  }
  for (const char* f :
       {"mav0/cam0_augmented/data.csv", "mav0/cam1_mask/sensor.yaml", "mav0/cam0_depth/data.csv", "poses.csv",
        "stats.csv", "frames.csv", "mav0/state_groundtruth_estimate0/data.csv"})
    EXPECT_TRUE(run.count(f)) << f;
}

TEST(EurocSink, OptionsLeaveStreamsOut) {
  const std::string out = test::output_dir("euroc_sink_options");
  fs::remove_all(out);
  PipelineParts p = test::pipeline_parts(kScenario);
  p.max_pairs = 2;
  auto sink = make_sink("euroc:" + out + "/raw,no-augmented,no-masks,no-plot", {p.rig});
  ASSERT_TRUE(sink) << sink.error().message;
  p.sinks.push_back(std::move(*sink));
  Pipeline pipeline(std::move(p));
  std::ostringstream o, e;
  ASSERT_TRUE(pipeline.run(o, e));
  EXPECT_TRUE(fs::exists(out + "/raw/mav0/cam0/data.csv"));
  EXPECT_TRUE(fs::exists(out + "/raw/stats.csv"));
  EXPECT_FALSE(fs::exists(out + "/raw/mav0/cam0_augmented"));
  EXPECT_FALSE(fs::exists(out + "/raw/mav0/cam1_mask"));
  EXPECT_FALSE(fs::exists(out + "/raw/stats.png"));
}

TEST(EurocSink, BadArgumentsAndAnExistingExportAreNamed) {
  const std::string out = test::output_dir("euroc_sink_bad");
  const Rig rig = Rig::paper_default();
  auto unknown = make_sink("euroc:" + out + "/x,jpeg", {rig});
  ASSERT_FALSE(unknown);
  EXPECT_EQ(
      unknown.error().message,
      "euroc sink: jpeg: unknown option (expected no-augmented, no-masks, no-plot, ground-truth or nav)");
  // nav: the clock and nav inputs of the recording a replay plays; none here, or one that is not there.
  auto no_replay = make_sink("euroc:" + out + "/x,nav", {rig});
  ASSERT_FALSE(no_replay);
  EXPECT_EQ(no_replay.error().message,
            "euroc sink: nav: the clock and nav inputs of the recording replayed; only `augrig replay REC` "
            "replays one");
  auto gone = make_sink("euroc:" + out + "/x,nav", {rig, {}, nullptr, out + "/no_such_recording"});
  ASSERT_FALSE(gone);
  EXPECT_EQ(gone.error().message.rfind("euroc sink: nav: ", 0), 0u) << gone.error().message;
  EXPECT_NE(gone.error().message.find("no_such_recording"), std::string::npos) << gone.error().message;
  EXPECT_FALSE(fs::exists(out + "/x/mav0"));
  auto empty = make_sink("euroc:,no-plot", {rig});
  ASSERT_FALSE(empty);
  EXPECT_EQ(empty.error().message, "euroc sink: expected a folder (euroc:DIR)");
  fs::create_directories(out + "/taken/mav0");
  auto taken = make_sink("euroc:" + out + "/taken", {rig});
  ASSERT_FALSE(taken);
  EXPECT_EQ(
      taken.error().message,
      "euroc sink: " + out + "/taken/mav0: exists already; export into a new folder (exports never mix)");
}

}  // namespace
}  // namespace augrig::pipeline
