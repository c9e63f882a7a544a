// augrig run and augrig cameras through the real binary: a simulated flight through the whole live
// pipeline into a recording that checks clean; two GigE Vision cameras (arv-fake-gv-camera-0.8
// processes on two loopback addresses) named by the rig's per-camera source URIs; bad sources and
// flags with their exit codes and messages.
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "core/conventions.hpp"
#include "render/rig.hpp"
#include "tests/support/fake_gv_camera.hpp"
#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

namespace fs = std::filesystem;
using test::augrig_binary;
using test::output_dir;
using test::run_command;

int augrig(const std::string& args, std::string* output = nullptr) {
  return run_command(augrig_binary() + " " + args + " 2>&1", output);
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(CmdRun, SimulatedFlightThroughThePipelineIntoARecording) {
  const std::string dir = output_dir("cmd_run_sim");
  std::string out;
  ASSERT_EQ(augrig("run --source 'sim://demo?rate=0&every=45' --record " + dir + "/rec --out " + dir +
                       " --status-every 0",
                   &out),
            0)
      << out;
  EXPECT_TRUE(contains(out, "(lockstep)")) << out;
  EXPECT_TRUE(contains(out, "Run summary over")) << out;
  EXPECT_TRUE(contains(out, "drops: camera")) << out;
  EXPECT_TRUE(contains(out, "dropped by the recorder")) << out;
  // Lockstep: everything the simulated cameras delivered pairs (the demo's dropped frames excepted).
  EXPECT_TRUE(contains(out, "processing 0 (queue 0, no pose 0, failed 0)")) << out;
  std::string check;
  EXPECT_EQ(augrig("check " + dir + "/rec", &check), 0) << check;
  EXPECT_TRUE(fs::exists(dir + "/stats.csv"));
}

TEST(CmdRun, TwoGigEVisionCamerasFromTheRigsSourceUris) {
  std::string why;
  if (!test::ensure_loopback_address("127.0.0.2", &why)) GTEST_SKIP() << why;
  test::FakeGvProcess left("127.0.0.1", "RUNL"), right("127.0.0.2", "RUNR");
  ASSERT_TRUE(left.start());
  ASSERT_TRUE(right.start());

  std::string listing;
  ASSERT_EQ(augrig("cameras", &listing), 0) << listing;
  EXPECT_TRUE(contains(listing, "aravis://127.0.0.2")) << listing;
  EXPECT_TRUE(contains(listing, "serial RUNR")) << listing;
  EXPECT_TRUE(contains(listing, "pixel formats: BayerBG8")) << listing;
  EXPECT_TRUE(contains(listing, "V4L2:")) << listing;

  // A small rig whose cameras name their sources; the fake cameras stream a 160x120 region.
  const std::string dir = output_dir("cmd_run_gige");
  Rig rig = Rig::paper_default();
  for (RigCamera& c : rig.cameras) c.model = CameraModel::pinhole_from_hfov(160, 120, deg_to_rad(56.0));
  rig.cameras[0].source_uri = "aravis://127.0.0.1?fps=20&roi=0,0,160,120&format=BayerRG8";
  rig.cameras[1].source_uri = "aravis://RUNR?fps=20&roi=0,0,160,120&format=BayerRG8";
  {
    std::ofstream f(dir + "/rig.yaml");
    f << rig_to_yaml(rig);
  }
  std::string out;
  ASSERT_EQ(augrig("run --rig " + dir + "/rig.yaml --scene " + test::data_path("scenes/contact.yaml") +
                       " --duration 3 --record " + dir + "/rec --status-every 1",
                   &out),
            0)
      << out;
  EXPECT_TRUE(contains(out, "(live)")) << out;
  EXPECT_TRUE(contains(out, "pair skew: p50")) << out;
  EXPECT_TRUE(contains(out, "clock left: host - device")) << out;
  EXPECT_TRUE(contains(out, "clock right: host - device")) << out;
  EXPECT_TRUE(contains(out, "stereo frames augmented")) << out;
  std::string check;
  EXPECT_EQ(augrig("check " + dir + "/rec", &check), 0) << check;
}

TEST(CmdRun, BadSourcesAndFlagsSayWhatIsWrong) {
  struct Case {
    std::string args;
    int code;
    std::string message;
  };
  const std::string scene = " --scene " + test::data_path("scenes/contact.yaml");
  for (const Case& c : std::vector<Case>{
           {"run", 2, "give --source URI"},
           {"run --source 'ftp://x'" + scene, 1, "unknown scheme 'ftp'"},
           {"run --source 'aravis://127.0.0.1'" + scene, 1, "one camera is not a stereo rig"},
           {"run --source 'sim://demo?speed=2'", 1, "unknown parameter speed for sim://"},
           {"run --source 'sim://no-such-scenario'", 1, "no-such-scenario"},
           {"run --source 'stereo:[mode=sync]//{aravis://a}{aravis://b}'" + scene, 1,
            "mode: expected timestamp or trigger_id"},
           {"run --source 'stereo://{aravis://a?fps=x}{aravis://b}'" + scene, 1, "fps: expected a number"},
           {"run --source 'replay:///nonexistent/rec'" + scene, 1, "/nonexistent/rec"},
           {"run --source 'sim://demo' --duration -1", 2, "--duration"},
       }) {
    std::string out;
    EXPECT_EQ(augrig(c.args, &out), c.code) << c.args << "\n" << out;
    EXPECT_TRUE(contains(out, c.message)) << c.args << "\n" << out;
    EXPECT_TRUE(contains(out, "augrig run: ")) << out;
  }
}

}  // namespace
}  // namespace augrig
