// augrig run and augrig cameras through the real binary: a simulated flight through the whole live
// pipeline into a recording that checks clean; two GigE Vision cameras (arv-fake-gv-camera-0.8
// processes on two loopback addresses) named by the rig's per-camera source URIs; bad sources and
// flags with their exit codes and messages.
#include <filesystem>
#include <fstream>
#include <thread>

#include <gtest/gtest.h>

#include "core/conventions.hpp"
#include "nav/imu_stream.hpp"
#include "nav/nmea.hpp"
#include "nav/udp_socket.hpp"
#include "recorder/reader.hpp"
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
  return test::run_augrig(args, output);
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
  EXPECT_TRUE(contains(out, "processing 0 (queue 0, failed 0), recorder 0")) << out;
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

// Live nav inputs given with --nav are recorded exactly as received: NMEA lines as text, IMU
// datagrams as bytes, with their arrival times; malformed input is counted in the ledger.
TEST(CmdRun, RecordsLiveNavInputsAsReceived) {
  const std::string dir = output_dir("cmd_run_nav");
  // Fixed ports: the run binds them; another test binding the same ports would fail loudly.
  const int nmea_port = 47000 + (getpid() % 1000), imu_port = nmea_port + 1000;
  std::string out;
  std::thread run([&] {
    augrig("run --source 'sim://demo?rate=1&every=30' --duration 4 --status-every 0 --record " + dir +
               "/rec --nav 'tanker.gps=udp://127.0.0.1:" + std::to_string(nmea_port) +
               "?format=nmea,tanker.imu=udp://127.0.0.1:" + std::to_string(imu_port) + "?format=imu'",
           &out);
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // the run has bound its sockets
  auto tx = nav::UdpSender::open("127.0.0.1", static_cast<std::uint16_t>(nmea_port));
  ASSERT_TRUE(tx) << tx.error().message;
  const std::vector<std::string> lines = {
      nav::nmea_sentence("GPGGA,120000.00,4807.0380,N,01131.0000,E,4,12,0.9,545.4,M,46.9,M,,"),
      "$GPGGA,120000.20,4807.0381,N,01131.0001,E,4,12,0.9,545.5,M,46.9,M,,*XX",  // bad checksum
  };
  for (const std::string& l : lines) ASSERT_TRUE(tx->send(l));
  auto imu = nav::ImuUdpSender::open("127.0.0.1", static_cast<std::uint16_t>(imu_port), ClockDomain::kGps);
  ASSERT_TRUE(imu) << imu.error().message;
  nav::ImuSample sample;
  sample.t_ns = 1'400'000'000'000'000'000;
  sample.dt_s = 0.01;
  sample.dtheta_rad = Eigen::Vector3d(1e-4, -2e-4, 3e-4);
  sample.dv_mps = Eigen::Vector3d(0.01, 0.0, -0.098);
  const std::vector<nav::ImuSample> samples = {sample};
  ASSERT_TRUE(imu->send(samples));
  run.join();
  ASSERT_TRUE(contains(out, "nav tanker.gps")) << out;
  EXPECT_TRUE(contains(out, "malformed 1")) << out;

  auto reader = recorder::RecordingReader::open(dir + "/rec");
  ASSERT_TRUE(reader) << reader.error().message;
  auto inputs = (*reader)->nav_inputs();
  ASSERT_TRUE(inputs) << inputs.error().message;
  std::vector<std::string> gps;
  int imu_datagrams = 0;
  for (const recorder::NavInputRecord& r : *inputs) {
    EXPECT_GT(r.arrival_ns, 0);
    if (r.stream == "tanker.gps") gps.push_back(r.data);
    if (r.stream == "tanker.imu") {
      EXPECT_TRUE(r.binary);
      auto d = nav::decode_imu_datagram(
          std::span(reinterpret_cast<const std::uint8_t*>(r.data.data()), r.data.size()));
      ASSERT_TRUE(d) << d.error().message;
      ASSERT_EQ(d->samples.size(), 1u);
      EXPECT_EQ(d->samples[0].t_ns, sample.t_ns);
      EXPECT_EQ(d->samples[0].dv_mps, sample.dv_mps);
      ++imu_datagrams;
    }
  }
  EXPECT_EQ(gps, lines) << "both lines, the malformed one too, byte for byte";
  EXPECT_EQ(imu_datagrams, 1);
}

// With a display (Xvfb here) and no --headless, run opens the live window and drives it from the
// pipeline's own thread; the run ends and summarises as headless.
TEST(CmdRun, OpensTheLiveWindowWhenADisplayIsPresent) {
  if (run_command("command -v xvfb-run > /dev/null") != 0) GTEST_SKIP() << "xvfb-run is not installed";
  const std::string dir = output_dir("cmd_run_window");
  std::string out;
  ASSERT_EQ(
      run_command("xvfb-run -a " + augrig_binary() + " run --source 'sim://demo?rate=0&every=90' --out " +
                      dir + " --status-every 0 2>&1",
                  &out),
      0)
      << out;
  EXPECT_TRUE(contains(out, "live display open")) << out;
  EXPECT_TRUE(contains(out, "stereo frames augmented")) << out;
  out.clear();
  ASSERT_EQ(
      run_command("xvfb-run -a " + augrig_binary() +
                      " run --headless --source 'sim://demo?rate=0&every=300' " + "--status-every 0 2>&1",
                  &out),
      0)
      << out;
  EXPECT_FALSE(contains(out, "live display open")) << "--headless keeps it headless";
}

// augrig demo with a display: the simulated flight in real time in the live window, recording on.
TEST(CmdRun, DemoOpensTheLiveWindowWhenADisplayIsPresent) {
  if (run_command("command -v xvfb-run > /dev/null") != 0) GTEST_SKIP() << "xvfb-run is not installed";
  const std::string dir = output_dir("cmd_run_demo_window");
  std::string out;
  ASSERT_EQ(
      run_command("xvfb-run -a " + augrig_binary() + " demo --out " + dir + " --every 15 --duration 4 2>&1",
                  &out),
      0)
      << out;
  EXPECT_TRUE(contains(out, "the flight in real time in the live window")) << out;
  EXPECT_TRUE(contains(out, "live display open")) << out;
  EXPECT_TRUE(contains(out, "recorded ")) << out;
  std::string check;
  EXPECT_EQ(augrig("check " + dir + "/recording", &check), 0) << check;
  // No display: the batch demo refuses the window-only flag.
  EXPECT_EQ(augrig("demo --out " + dir + "/batch --headless --duration 4", &out), 2) << out;
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
           {"run --source 'sim://demo' --nav 'udp://127.0.0.1:1'", 2, "--nav: expected STREAM=URI"},
           {"run --source 'sim://demo' --nav 'gps=udp://127.0.0.1:1?format=xml'", 1, "format"},
       }) {
    std::string out;
    EXPECT_EQ(augrig(c.args, &out), c.code) << c.args << "\n" << out;
    EXPECT_TRUE(contains(out, c.message)) << c.args << "\n" << out;
    EXPECT_TRUE(contains(out, "augrig run: ")) << out;
  }
}

}  // namespace
}  // namespace augrig
