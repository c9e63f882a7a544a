// augrig run and augrig cameras through the real binary: a simulated flight through the whole live
// pipeline into a recording that checks clean; two GigE Vision cameras (arv-fake-gv-camera-0.8
// processes on two loopback addresses) named by the rig's per-camera source URIs; bad sources and
// flags with their exit codes and messages.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <regex>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/conventions.hpp"
#include "nav/imu_stream.hpp"
#include "nav/nmea.hpp"
#include "nav/udp_socket.hpp"
#include "recorder/reader.hpp"
#include "render/rig.hpp"
#include "render/video_codec.hpp"
#include "ros2/messages.hpp"
#include "sim/flight.hpp"
#include "sim/flight_source.hpp"
#include "sim/scenario.hpp"
#include "sim/sensors.hpp"
#include "tests/support/fake_gv_camera.hpp"
#include "tests/support/sanitizer.hpp"
#include "tests/support/test_support.hpp"
#include "tests/support/tmpfs.hpp"
#include "tests/support/window_shot.hpp"
#include "tests/support/ws_test_client.hpp"

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

// The summary's "frames read: left L, right R = 2 x P pairs + U unpaired + Q dropped from full
// queues + N pending at the stop" line, as numbers.
struct FrameAccount {
  std::uint64_t left = 0, right = 0, pairs = 0, unpaired = 0, queue = 0, pending = 0;
};
std::optional<FrameAccount> frame_account(const std::string& out) {
  static const std::regex re(
      "frames read: left ([0-9]+), right ([0-9]+) = 2 x ([0-9]+) pairs \\+ ([0-9]+) unpaired \\+ ([0-9]+) "
      "dropped from full queues \\+ ([0-9]+) pending at the stop");
  std::smatch m;
  if (!std::regex_search(out, m, re)) return std::nullopt;
  return FrameAccount{std::stoull(m[1]), std::stoull(m[2]), std::stoull(m[3]),
                      std::stoull(m[4]), std::stoull(m[5]), std::stoull(m[6])};
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
  EXPECT_TRUE(contains(out, "processing 0 (queue 0, failed 0 pairs, pending at the stop 0), recorder 0"))
      << out;
  std::string check;
  EXPECT_EQ(augrig("check " + dir + "/rec", &check), 0) << check;
  EXPECT_TRUE(fs::exists(dir + "/stats.csv"));
}

// --ground-truth with --record alone: every recorded frame holds both cameras' receiver depth,
// finite exactly where its mask has the receiver; without --record or --every it is a usage error.
TEST(CmdRun, GroundTruthIsStoredInTheRecording) {
  const std::string dir = output_dir("cmd_run_ground_truth");
  std::string out;
  ASSERT_EQ(
      augrig(
          "run --source 'sim://demo?rate=0&every=90' --frames 2 --headless --status-every 0 --ground-truth "
          "--record " +
              dir + "/rec 2>&1",
          &out),
      0)
      << out;
  auto rd = recorder::RecordingReader::open(dir + "/rec");
  ASSERT_TRUE(rd) << rd.error().message;
  ASSERT_EQ((*rd)->frame_count(), 2u);
  std::size_t receiver_px = 0;
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_TRUE((*rd)->has_depth(i));
    auto f = (*rd)->read_frame(i);
    ASSERT_TRUE(f) << f.error().message;
    for (int c = 0; c < 2; ++c) {
      ASSERT_FALSE(f->receiver_depth[c].empty());
      const DepthImage z = f->receiver_depth[c].image();
      const Image& m = f->mask[c];
      ASSERT_EQ(z.width, m.width());
      std::size_t mismatched = 0;
      for (int y = 0; y < m.height(); ++y)
        for (int x = 0; x < m.width(); ++x) {
          const bool receiver = (m.row(y)[x] & kMaskReceiver) != 0;
          receiver_px += receiver;
          mismatched += receiver != std::isfinite(z.at(x, y));
        }
      EXPECT_EQ(mismatched, 0u) << "frame " << i << " camera " << c;
    }
  }
  EXPECT_GT(receiver_px, 1000u);
  EXPECT_EQ(augrig("run --source 'sim://demo?rate=0' --frames 1 --headless --ground-truth 2>&1", &out), 2);
  EXPECT_TRUE(contains(out, "--ground-truth needs --out DIR and --every K")) << out;
  EXPECT_TRUE(contains(out, "or --record DIR")) << out;
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
  EXPECT_TRUE(contains(listing, "now: ")) << listing;

  // A rig template for the two cameras: serial-based URIs with their current format and rate, their
  // size; it loads, and `rig show` reads it.
  {
    const std::string tdir = output_dir("cmd_run_gige_template");
    ASSERT_EQ(augrig("cameras --rig " + tdir + "/rig.yaml", &listing), 0) << listing;
    auto t = load_rig(tdir + "/rig.yaml");
    ASSERT_TRUE(t) << t.error().message;
    std::vector<std::string> uris = {t->cameras[0].source_uri, t->cameras[1].source_uri};
    std::sort(uris.begin(), uris.end());
    EXPECT_EQ(uris[0].rfind("aravis://RUNL?format=", 0), 0u) << uris[0];
    EXPECT_EQ(uris[1].rfind("aravis://RUNR?format=", 0), 0u) << uris[1];
    EXPECT_TRUE(contains(uris[0], "&fps=")) << uris[0];
    EXPECT_GT(t->cameras[0].model.width_px, 0);
    std::string shown;
    EXPECT_EQ(augrig("rig show " + tdir + "/rig.yaml", &shown), 0) << shown;
    EXPECT_TRUE(contains(shown, "source aravis://RUN")) << shown;
  }

  // A small rig whose cameras name their sources; the fake cameras stream a 160x120 region.
  const std::string dir = output_dir("cmd_run_gige");
  Rig rig = Rig::paper_default();
  for (RigCamera& c : rig.cameras) c.model = CameraModel::pinhole_from_hfov(160, 120, deg_to_rad(56.0));
  rig.cameras[0].source_uri = "aravis://127.0.0.1?fps=20&roi=0,0,160,120&format=BayerRG8";
  rig.cameras[1].source_uri = "aravis://RUNR?fps=20&roi=0,0,160,120&format=BayerRG8";
  // Free-running cameras, each with its own clock, paired on host time through the clock estimates.
  // Both fake cameras fire at the same instant of the host's clock, and on 2 cores their frames'
  // arrivals queue behind each other: a constant 1-3 ms of latency that no arrival-time estimate
  // can see comes between them (docs/PAIRING.md). A fifth of the 50 ms period pairs them still.
  rig.pairing.tolerance_us = 10000;
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
  EXPECT_TRUE(contains(out, "pairing by timestamp, tolerance 10000.0 us, each camera's clock to host time"))
      << out;
  EXPECT_TRUE(contains(out, "(live)")) << out;
  // The banner: each camera as set, the URI's settings and the device's own.
  EXPECT_TRUE(contains(out, "  aravis://RUNR: 160x120 BayerRG8 at 20 fps, exposure ")) << out;
  EXPECT_TRUE(contains(out, "serial RUNR at 127.0.0.2")) << out;
  EXPECT_TRUE(contains(out, "pair skew: p50")) << out;
  EXPECT_TRUE(contains(out, "clock left: host - device")) << out;
  EXPECT_TRUE(contains(out, "clock right: host - device")) << out;
  EXPECT_TRUE(contains(out, "stereo frames augmented")) << out;
  // 3 s at 20 fps is 60 pairs; the first few frames queue while the augmenter starts.
  std::smatch m;
  ASSERT_TRUE(std::regex_search(out, m, std::regex(R"(run: (\d+) stereo frames augmented)"))) << out;
  EXPECT_GE(std::stoi(m[1]), 15) << out;
  std::string check;
  EXPECT_EQ(augrig("check " + dir + "/rec", &check), 0) << check;
}

// `augrig run` for `seconds` on the two fake GigE cameras at 127.0.0.1 and 127.0.0.2 (160x120
// BayerRG8 at 20 fps, named by the rig's source URIs), recording into DIR/rec.
int run_two_fake_cameras(const std::string& dir, int seconds, std::string* out) {
  Rig rig = Rig::paper_default();
  for (RigCamera& c : rig.cameras) c.model = CameraModel::pinhole_from_hfov(160, 120, deg_to_rad(56.0));
  // Plain UDP sockets: see docs/CAPTURE.md on Aravis' packet socket when a stream dies.
  rig.cameras[0].source_uri = "aravis://127.0.0.1?fps=20&roi=0,0,160,120&format=BayerRG8&packet_socket=0";
  rig.cameras[1].source_uri = "aravis://127.0.0.2?fps=20&roi=0,0,160,120&format=BayerRG8&packet_socket=0";
  {
    std::ofstream f(dir + "/rig.yaml");
    f << rig_to_yaml(rig);
  }
  return augrig("run --rig " + dir + "/rig.yaml --scene " + test::data_path("scenes/contact.yaml") +
                    " --duration " + std::to_string(seconds) + " --headless --status-every 0 --record " +
                    dir + "/rec",
                out);
}

// A camera lost mid-run (its process killed) and back (restarted): the run says so in plain words,
// goes on with the other camera's frames counted, pairs again after the reconnection, and ends
// with a valid recording.
TEST(CmdRun, CameraLostMidRunIsReportedAndTheRunGoesOn) {
  std::string why;
  if (!test::ensure_loopback_address("127.0.0.2", &why)) GTEST_SKIP() << why;
  test::FakeGvProcess left("127.0.0.1", "LOSTL"), right("127.0.0.2", "LOSTR");
  ASSERT_TRUE(left.start());
  ASSERT_TRUE(right.start());
  const std::string dir = output_dir("cmd_run_camera_lost");
  std::string out;
  int code = -1;
  std::thread run([&] { code = run_two_fake_cameras(dir, 9, &out); });
  std::this_thread::sleep_for(std::chrono::seconds(3));
  right.kill();
  std::this_thread::sleep_for(std::chrono::seconds(2));
  ASSERT_TRUE(right.start());
  run.join();
  EXPECT_EQ(code, 0) << out;
  EXPECT_TRUE(contains(out, "lost")) << out;
  EXPECT_TRUE(contains(out, "lost 1 time(s), reconnected 1 time(s)")) << out;
  EXPECT_TRUE(contains(out, "stereo frames augmented")) << out;
  std::string check;
  EXPECT_EQ(augrig("check " + dir + "/rec", &check), 0) << check;
  auto reader = recorder::RecordingReader::open(dir + "/rec");
  ASSERT_TRUE(reader) << reader.error().message;
  auto events = (*reader)->events();
  ASSERT_TRUE(events);
  bool lost_event = false;
  for (const recorder::EventRecord& e : *events) lost_event = lost_event || contains(e.text, "lost");
  EXPECT_TRUE(lost_event) << "the loss is an event in the recording";
  // Frames were paired before the loss and after the reconnection (20 fps for 9 s, 2-3 s lost).
  EXPECT_GT((*reader)->frame_count(), 60u);
}

// A camera that is lost and never comes back fails the run (exit 1, naming it); it exited 0 with
// "reconnected 0 time(s)". The frames read still add up.
TEST(CmdRun, CameraLostForGoodFailsTheRun) {
  std::string why;
  if (!test::ensure_loopback_address("127.0.0.2", &why)) GTEST_SKIP() << why;
  test::FakeGvProcess left("127.0.0.1", "GONEL"), right("127.0.0.2", "GONER");
  ASSERT_TRUE(left.start());
  ASSERT_TRUE(right.start());
  const std::string dir = output_dir("cmd_run_camera_gone");
  std::string out;
  int code = -1;
  std::thread run([&] { code = run_two_fake_cameras(dir, 6, &out); });
  std::this_thread::sleep_for(std::chrono::seconds(2));
  right.kill();
  run.join();
  EXPECT_EQ(code, 1) << out;
  EXPECT_TRUE(contains(out, "aravis://127.0.0.2")) << out;
  EXPECT_TRUE(contains(out, "was lost and never came back")) << out;
  const auto acc = frame_account(out);
  ASSERT_TRUE(acc) << out;
  EXPECT_EQ(acc->left + acc->right, 2 * acc->pairs + acc->unpaired + acc->queue + acc->pending) << out;
  std::string check;
  EXPECT_EQ(augrig("check " + dir + "/rec", &check), 0) << check;
}

// Live nav inputs given with --nav are recorded exactly as received: NMEA lines as text, IMU
// datagrams as bytes, with their arrival times; malformed input is counted in the ledger.
// Whether a UDP socket of this machine is bound to `port` (from /proc/net/udp): the child run has
// bound its inputs. Waits up to `timeout`.
bool udp_port_bound(int port, std::chrono::seconds timeout) {
  char hex[8];
  std::snprintf(hex, sizeof hex, ":%04X ", port);
  const auto until = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < until) {
    std::ifstream in("/proc/net/udp");
    std::string line;
    while (std::getline(in, line)) {
      // "  sl  local_address rem_address ...": the local address is the second field.
      std::istringstream f(line);
      std::string sl, local;
      f >> sl >> local;
      if ((local + " ").find(hex) != std::string::npos) return true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return false;
}

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
  // Joined however the test ends (an ASSERT returns early; a joinable thread would abort the binary).
  struct Joiner {
    std::thread& t;
    ~Joiner() {
      if (t.joinable()) t.join();
    }
  } joiner{run};
  // Sent once the run has bound both inputs (slow to start under the sanitizers, say).
  ASSERT_TRUE(udp_port_bound(nmea_port, std::chrono::seconds(30)) &&
              udp_port_bound(imu_port, std::chrono::seconds(30)))
      << "augrig run never bound its nav input ports";
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

// --nav sim: the simulated GPS and IMU of both aircraft go over UDP on loopback, in real time, into
// the live inputs; the live fusion gives each frame's receiver pose. The recorded poses are checked
// against the simulator's truth for the same frames.
TEST(CmdRun, LiveNavPosesFromTheSimulatedStreamsMatchTheTruth) {
  const std::string dir = output_dir("cmd_run_live_nav");
  std::string out;
  ASSERT_EQ(
      augrig(
          "run --source 'sim://demo?every=3' --nav sim --duration 8 --headless --status-every 0 --record " +
              dir + "/rec",
          &out),
      0)
      << out;
  EXPECT_TRUE(contains(out, "poses from the live nav")) << out;
  EXPECT_TRUE(contains(out, "nav tanker: fused")) << out;
  EXPECT_TRUE(contains(out, "nav receiver: fused")) << out;
  EXPECT_TRUE(contains(out, "latency mid-exposure to recorder: p50")) << out;
  EXPECT_TRUE(contains(out, "lost 0\n")) << out;

  // The truth of every frame of the flight, by the left camera's timestamp.
  auto sc = sim::builtin_scenario("demo");
  ASSERT_TRUE(sc);
  auto flight = sim::Flight::create(*sc);
  ASSERT_TRUE(flight);
  std::map<TimestampNs, sim::FrameTruth> truth;
  for (const sim::FrameTruth& t :
       sim::frame_truths(*sc, *flight, sim::simulate_sensors(*sc, *flight).cameras))
    if (t.camera == 0) truth[t.t_camera_ns] = t;

  auto reader = recorder::RecordingReader::open(dir + "/rec");
  ASSERT_TRUE(reader) << reader.error().message;
  std::size_t checked = 0, without_pose = 0;
  double max_err_m = 0;
  for (std::size_t i = 0; i < (*reader)->frame_count(); ++i) {
    auto f = (*reader)->read_frame_info(i);
    ASSERT_TRUE(f) << f.error().message;
    if (!f->receiver_present.value_or(false)) {
      ++without_pose;  // the filters' first second
      continue;
    }
    const auto it = truth.find(f->raw.left.t_ns);
    ASSERT_NE(it, truth.end());
    if (it->second.t_true_s < 3.0) continue;
    ASSERT_TRUE(f->T_body_receiver);
    max_err_m = std::max(
        max_err_m, (f->T_body_receiver->translation_m - it->second.T_body_receiver.translation_m).norm());
    EXPECT_GT(f->sigma_pos_m, 0.0);
    ++checked;
  }
  std::printf(
      "  %zu recorded frames after 3 s: receiver position max error %.1f mm; %zu frames without a pose\n",
      checked, 1e3 * max_err_m, without_pose);
  EXPECT_GT(checked, 10u);
  EXPECT_LT(max_err_m, 0.1);
  EXPECT_LT(without_pose, 25u);
  std::string check;
  EXPECT_EQ(augrig("check " + dir + "/rec", &check), 0) << check;
}

// --camera-clock online: each camera's clock estimated during the run, in the summary and recorded
// (every fit an event). The demo flies straight and level: nothing to estimate from, so nothing is
// applied and the poses are those of the configured offsets (the recovery itself is
// tests/pipeline/camera_clock_online_test.cpp's).
TEST(CmdRun, CameraClocksOnlineAreSummarisedAndRecorded) {
  const std::string dir = output_dir("cmd_run_camera_clock");
  std::string out;
  ASSERT_EQ(
      augrig("run --source 'sim://demo?every=3' --nav sim --camera-clock online --duration 14 --headless "
             "--status-every 0 --record " +
                 dir + "/rec",
             &out),
      0)
      << out;
  EXPECT_TRUE(contains(out, "camera clocks estimated online, applied at 1-sigma <= 0.5 ms")) << out;
  EXPECT_TRUE(contains(out, "camera clock left: ")) << out;
  EXPECT_TRUE(contains(out, "camera clock right: ")) << out;
  // Nothing applied: the poses keep the scenario's configured offsets (1.2 and 1.25 ms).
  EXPECT_TRUE(contains(out, "prior +1.200 ms in use [")) << out;
  EXPECT_TRUE(contains(out, "prior +1.250 ms in use [")) << out;
  auto reader = recorder::RecordingReader::open(dir + "/rec");
  ASSERT_TRUE(reader) << reader.error().message;
  EXPECT_TRUE(contains((*reader)->meta("camera_clock"), "t_gps = t_camera - offset"));
  auto events = (*reader)->events();
  ASSERT_TRUE(events);
  int fits[2] = {0, 0};
  for (const recorder::EventRecord& e : *events) {
    fits[0] += contains(e.text, "camera_clock camera=left state=") ? 1 : 0;
    fits[1] += contains(e.text, "camera_clock camera=right state=") ? 1 : 0;
    EXPECT_FALSE(contains(e.text, "applied=1")) << e.text;
  }
  // A fit needs rotations between frames tracked close together: a sanitizer's build augments
  // 1280x960 pairs about once a second in real time, too far apart (the 480x360 flight of the
  // next test is fitted there too).
  if (!test::kSanitized) {
    EXPECT_GE(fits[0], 1) << out;
    EXPECT_GE(fits[1], 1) << out;
  }
  std::string check;
  EXPECT_EQ(augrig("check " + dir + "/rec", &check), 0) << check;
}

// --camera-clock online through the real binary: 60 s behind a tanker rolling into and out of 45 deg
// banked turns, whose cameras' clocks are off by +3.7 ms and -2.4 ms (drifting -3 ppm) while the
// rig's calibration says 0 (sensors.cameras.clock_offset_assumed_ns). The poses start from the
// wrong 0; each camera's estimate is applied within the 60 s and is then within 1 ms of the truth,
// in the summary and in the recorded fits.
TEST(CmdRun, CameraClocksOnlineConvergeWithinOneMillisecondInSixtySecondsOfManoeuvring) {
  const std::string dir = output_dir("cmd_run_camera_clock_converge");
  Rig rig = Rig::paper_default();
  for (RigCamera& c : rig.cameras) {
    c.model = CameraModel::pinhole_from_hfov(480, 360, deg_to_rad(56));
    c.model.distortion = DistortionModel::kRadTan;
    c.model.coeffs = {-0.05, 0.01, 0, 0, 0};
  }
  std::ofstream(dir + "/rig.yaml") << rig_to_yaml(rig);
  constexpr std::int64_t kStartGpsNs = 1'401'278'418'000'000'000;
  std::ofstream(dir + "/racetrack.yaml") << R"(augrig_scenario: 1
name: clock-racetrack
duration_s: 60
seed: 3
start: {gps_time_ns: )" << kStartGpsNs << R"(, lat_deg: 51.0, lon_deg: -1.0, alt_m: 7000}
rig: rig.yaml
tanker: {pattern: racetrack, heading_deg: 90, speed_mps: 120, bank_deg: 45, leg_length_m: 600, roll_in_s: 4}
receiver:
  contact: {elevation_deg: 30, azimuth_deg: 0, extension_m: 3.5}
  phases:
    - {name: observation, duration_s: 10, offset_m: [-30, 2, 12]}
    - {name: to-pre-contact, duration_s: 20, offset_m: [-15, 0, 4]}
    - {name: pre-contact, duration_s: 30}
sensors:
  tanker:
    imu: {preset: tactical, rate_hz: 200}
    gps: {rate_hz: 10, lever_arm_m: [5.0, 0.0, -3.5], latency_s: 0.03, heading: true}
  receiver:
    imu: {preset: tactical, rate_hz: 200}
    gps: {rate_hz: 10, lever_arm_m: [1.0, 0.0, -1.2], latency_s: 0.03}
  cameras:
    fps: 30
    clock_offset_ns: [3700000, -2400000]
    clock_drift_ppm: [0, -3]
    clock_offset_assumed_ns: 0
    jitter_ns: 20000
    bayer: RGGB
    noise: 2
)";
  std::string out;
  ASSERT_EQ(augrig("run --source 'sim://" + dir +
                       "/racetrack.yaml' --nav sim --camera-clock online --headless "
                       "--status-every 0 --record " +
                       dir + "/rec",
                   &out),
            0)
      << out;
  EXPECT_TRUE(contains(out, "camera clocks estimated online")) << out;
  // The truth at a camera time: offset + drift x the time since the start.
  const auto truth_ms = [&](int c, long long t_camera_ns) {
    const double t_s = static_cast<double>(t_camera_ns - kStartGpsNs) * 1e-9;
    return c == 0 ? 3.7 : -2.4 - 3e-6 * t_s * 1e3;
  };
  auto reader = recorder::RecordingReader::open(dir + "/rec");
  ASSERT_TRUE(reader) << reader.error().message;
  auto events = (*reader)->events();
  ASSERT_TRUE(events);
  const std::regex fit(
      R"(camera_clock camera=(left|right) state=(\S+) applied=(\d) offset_ms=(\S+) sigma_ms=(\S+) .*reference_camera_ns=(-?\d+) prior_offset_ms=(\S+))");
  int applied_fits[2] = {0, 0};
  double last_error_ms[2] = {1e9, 1e9}, last_sigma_ms[2] = {0, 0};
  for (const recorder::EventRecord& e : *events) {
    std::smatch m;
    if (!std::regex_search(e.text, m, fit)) continue;
    const int c = m[1] == "left" ? 0 : 1;
    EXPECT_EQ(std::stod(m[7]), 0.0) << "the prior is the assumed 0: " << e.text;
    if (m[3] != "1") continue;
    ++applied_fits[c];
    const double sigma_ms = std::stod(m[5]);
    EXPECT_LE(sigma_ms, 0.5 + 1e-9) << "applied only when confident: " << e.text;
    last_error_ms[c] = std::stod(m[4]) - truth_ms(c, std::stoll(m[6]));
    last_sigma_ms[c] = sigma_ms;
    // Honest: within 3 of its 1-sigma (and never more than 1 ms off) at every fit applied.
    EXPECT_LE(std::abs(last_error_ms[c]), std::max(1.0, 3 * sigma_ms)) << e.text;
  }
  for (int c = 0; c < 2; ++c) {
    SCOPED_TRACE(c == 0 ? "left" : "right");
    EXPECT_GE(applied_fits[c], 1) << out;
    EXPECT_LE(std::abs(last_error_ms[c]), 1.0) << out;
    EXPECT_LE(std::abs(last_error_ms[c]), 3 * last_sigma_ms[c] + 0.05) << out;
    std::printf("  %s: %d fits applied, the last %+.3f ms from the truth (1-sigma %.3f ms)\n",
                c == 0 ? "left" : "right", applied_fits[c], last_error_ms[c], last_sigma_ms[c]);
  }
  // The summary: both applied, each within 1 ms of its truth (the right one's mid-flight value);
  // a later fit not confident enough to apply is shown beside it ("applied (latest fit: ...)").
  const double truth_mid_ms[2] = {3.7, -2.4 - 3e-6 * 30e3};
  for (int c = 0; c < 2; ++c) {
    std::smatch m;
    const std::regex line(
        std::string("\ncamera clock ") + (c == 0 ? "left" : "right") +
        R"(: ([-+]\d+\.\d+) \+- (\S+) ms, .*, applied(?: \([^)]*\))? \[(\d+) frames tracked)");
    ASSERT_TRUE(std::regex_search(out, m, line)) << out;
    EXPECT_NEAR(std::stod(m[1]), truth_mid_ms[c], 1.0) << m[0];
    EXPECT_GT(std::stoi(m[3]), 300) << m[0];  // about 15 frames/s a camera tracked (900) on an idle machine
  }
}

// Nav faults while running: the receiver's GPS silent for 1.5 s, then its IMU for 1 s. The run goes
// on, every frame is still augmented and recorded, and the stale stretches are events in plain words.
TEST(CmdRun, StaleNavIsMarkedAndTheRunGoesOn) {
  const std::string dir = output_dir("cmd_run_stale_nav");
  std::string out;
  ASSERT_EQ(
      augrig("run --source 'sim://demo?every=3' --nav sim --nav-fault receiver.gps=2.5-4,receiver.imu=5-6 "
             "--duration 10 --headless --status-every 0 --record " +
                 dir + "/rec",
             &out),
      0)
      << out;
  EXPECT_TRUE(contains(out, "nav stale from pair")) << out;
  EXPECT_TRUE(contains(out, "receiver GPS: no data for")) << out;
  EXPECT_TRUE(contains(out, "receiver IMU: no data for")) << out;
  EXPECT_TRUE(contains(out, "nav good again from pair")) << out;
  auto reader = recorder::RecordingReader::open(dir + "/rec");
  ASSERT_TRUE(reader) << reader.error().message;
  auto events = (*reader)->events();
  ASSERT_TRUE(events);
  int stale = 0, good = 0;
  for (const recorder::EventRecord& e : *events) {
    stale += contains(e.text, "nav stale from pair") ? 1 : 0;
    good += contains(e.text, "nav good again from pair") ? 1 : 0;
  }
  EXPECT_GE(stale, 3);  // the start, the GPS silence, the IMU silence
  EXPECT_GE(good, 3);
  // Every pair augmented was recorded, stale or not.
  const std::size_t pos = out.find("stereo frames augmented");
  ASSERT_NE(pos, std::string::npos);
  const std::size_t start = out.rfind("run: ", pos) + 5;
  EXPECT_EQ(std::stoul(out.substr(start)), (*reader)->frame_count()) << out;
}

// The recorder's disk fills (a file size limit here): the recording stops with a clear error and
// stays valid, the pipeline goes on to the end of the run.
TEST(CmdRun, DiskFullEndsTheRecordingNotTheRun) {
  const std::string dir = output_dir("cmd_run_disk_full");
  std::string out;
  // ulimit -f counts 1024-byte blocks: 80 MB, about 20 stereo frames (4 MB each), so that several
  // commits (every 250 ms) land before it fills whatever the pace (at 30 MB a burst of frames at
  // the start could fill the first transaction, leaving none committed), and the run goes on
  // for seconds after.
  const int code =
      run_command("ulimit -f 80000 && " + augrig_binary() +
                      " run --source 'sim://demo?every=3' --duration 10 --headless --status-every 0 "
                      "--record " +
                      dir + "/rec 2>&1",
                  &out);
  EXPECT_EQ(code, 1) << out;
  EXPECT_TRUE(contains(out, "recording stopped:")) << out;
  EXPECT_TRUE(contains(out, "the run goes on")) << out;
  EXPECT_TRUE(contains(out, "Run summary over")) << out;
  auto reader = recorder::RecordingReader::open(dir + "/rec");
  ASSERT_TRUE(reader) << reader.error().message;
  const std::size_t recorded = (*reader)->frame_count();
  const std::size_t pos = out.find("stereo frames augmented");
  ASSERT_NE(pos, std::string::npos);
  const std::size_t augmented = std::stoul(out.substr(out.rfind("run: ", pos) + 5));
  std::printf("  %zu pairs augmented, %zu recorded before the disk filled\n", augmented, recorded);
  EXPECT_GT(recorded, 0u);
  EXPECT_GT(augmented, recorded + 10) << "the pipeline ran on after the recorder stopped";
  std::string check;
  EXPECT_EQ(augrig("check " + dir + "/rec", &check), 0) << check;
}

// Every frame read is in a pair or in a ledger row with its first and last timestamps, the frames
// still queued when a run is stopped by --duration included (they were in no row: read - 2 pairs -
// ledger was 4 in every run); events carry their time.
TEST(CmdRun, StoppedRunsLedgerAddsUpWithTimestamps) {
  const std::string dir = output_dir("cmd_run_ledger");
  std::string out;
  ASSERT_EQ(augrig("run --source 'sim://demo?every=3' --duration 4 --headless --status-every 0 --record " +
                       dir + "/rec",
                   &out),
            0)
      << out;
  const auto acc = frame_account(out);
  ASSERT_TRUE(acc) << out;
  EXPECT_EQ(acc->left + acc->right, 2 * acc->pairs + acc->unpaired + acc->queue + acc->pending) << out;
  auto reader = recorder::RecordingReader::open(dir + "/rec");
  ASSERT_TRUE(reader) << reader.error().message;
  auto drops = (*reader)->drops();
  ASSERT_TRUE(drops) << drops.error().message;
  std::uint64_t ledger = 0;
  for (const recorder::DropRecord& d : *drops) {
    if (d.item != "frame") continue;
    if (d.stage == recorder::DropStage::kPairing || d.stage == recorder::DropStage::kProcessing) {
      ledger += d.count;
      EXPECT_GT(d.first_t_ns, 0) << d.reason;
      EXPECT_GE(d.last_t_ns, d.first_t_ns) << d.reason;
    }
  }
  EXPECT_EQ((*reader)->frame_count(), acc->pairs) << out;
  EXPECT_EQ(acc->left + acc->right, 2 * (*reader)->frame_count() + ledger) << out;
  auto events = (*reader)->events();
  ASSERT_TRUE(events);
  for (const recorder::EventRecord& e : *events) EXPECT_GT(e.t_ns, 0) << e.text;
}

// A full disk (a 20 MB tmpfs) stops the recording; whether the stop comes from a transaction or from
// the WAL checkpoint, the recording is closed with the ledger the terminal shows.
TEST(CmdRun, FullDiskRecordingIsClosedWithTheTrueLedger) {
  for (int round = 0; round < 2; ++round) {
    SCOPED_TRACE("round " + std::to_string(round));
    const test::ScopedTmpfs fs(output_dir("cmd_run_full_disk_mnt"), 20u << 20);
    if (!fs.mounted()) GTEST_SKIP() << fs.error();
    std::string out;
    EXPECT_EQ(
        augrig("run --source 'sim://demo?every=3&rate=0' --duration 5 --headless --status-every 0 --record " +
                   fs.dir() + "/rec",
               &out),
        1)
        << out;
    EXPECT_TRUE(contains(out, "recording stopped:")) << out;
    // The recorder's drops: frames, and nav inputs or events (a phase event after the disk filled).
    static const std::regex dropped(
        "recorded ([0-9]+) stereo frames to .* \\(([0-9]+) dropped by the recorder(, and ([0-9]+) nav inputs "
        "or "
        "events)?\\)");
    std::smatch m;
    ASSERT_TRUE(std::regex_search(out, m, dropped)) << out;
    const std::uint64_t small = m[4].matched ? std::stoull(m[4].str()) : 0;
    auto reader = recorder::RecordingReader::open(fs.dir() + "/rec");
    ASSERT_TRUE(reader) << reader.error().message;
    EXPECT_NE((*reader)->meta("summary.status"), "") << "not closed";
    EXPECT_EQ((*reader)->meta("summary.frames"), m[1].str());
    EXPECT_EQ((*reader)->meta("summary.drops.recorder"), std::to_string(std::stoull(m[2].str()) + small));
    std::string check;
    EXPECT_EQ(augrig("check " + fs.dir() + "/rec", &check), 0) << check;
  }
}

// The batch demo with --record on a full disk exits 1, as run does (it exited 0).
TEST(CmdRun, DemoRecordingOnAFullDiskFailsTheDemo) {
  const test::ScopedTmpfs fs(output_dir("cmd_run_demo_full_disk_mnt"), 12u << 20);
  if (!fs.mounted()) GTEST_SKIP() << fs.error();
  const std::string out_dir = output_dir("cmd_run_demo_full_disk_out");
  std::string out;
  EXPECT_EQ(
      augrig("demo --headless --frames 40 --every 30 --out " + out_dir + " --record " + fs.dir() + "/rec",
             &out),
      1)
      << out;
  EXPECT_TRUE(contains(out, "augrig demo: the recording stopped:")) << out;
  EXPECT_TRUE(fs::exists(out_dir + "/stats.csv"));
  auto reader = recorder::RecordingReader::open(fs.dir() + "/rec");
  ASSERT_TRUE(reader) << reader.error().message;
  EXPECT_NE((*reader)->meta("summary.status"), "") << "not closed";
  EXPECT_NE((*reader)->meta("summary.status"), "ok");
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

// Faults with the window open (Xvfb): the receiver's GPS silent and the disk full in one run. The
// window keeps being drawn to the end (the display latency counts every pair, far more than the
// recorder took), the stale stretch is reported, and the recording stays valid.
TEST(CmdRun, FaultsWithTheWindowOpenKeepItRunning) {
  if (run_command("command -v xvfb-run > /dev/null") != 0) GTEST_SKIP() << "xvfb-run is not installed";
  const std::string dir = output_dir("cmd_run_window_faults");
  std::string out;
  const int code =
      run_command("ulimit -f 30000 && xvfb-run -a " + augrig_binary() +
                      " run --source 'sim://demo?every=3' --nav sim --nav-fault receiver.gps=2.5-4 "
                      "--duration 9 --status-every 0 --out " +
                      dir + " --record " + dir + "/rec 2>&1",
                  &out);
  EXPECT_EQ(code, 1) << out;  // the recording stopped early
  EXPECT_TRUE(contains(out, "live display open")) << out;
  EXPECT_TRUE(contains(out, "recording stopped:")) << out;
  EXPECT_TRUE(contains(out, "receiver GPS: no data for")) << out;
  const std::size_t pos = out.find("latency mid-exposure to display: ");
  ASSERT_NE(pos, std::string::npos) << out;
  const std::size_t open = out.find('(', pos);
  ASSERT_NE(open, std::string::npos);
  const unsigned long drawn = std::stoul(out.substr(open + 1));
  auto reader = recorder::RecordingReader::open(dir + "/rec");
  ASSERT_TRUE(reader) << reader.error().message;
  std::printf("  %lu pairs drawn in the window, %zu recorded before the disk filled\n", drawn,
              (*reader)->frame_count());
  EXPECT_GT(drawn, (*reader)->frame_count() + 10);
  std::string check;
  EXPECT_EQ(augrig("check " + dir + "/rec", &check), 0) << check;
}

// augrig demo with a display: the simulated flight in real time in the live window; it records only
// when asked, and the same flags mean what they mean in the batch demo.
TEST(CmdRun, DemoOpensTheLiveWindowWhenADisplayIsPresent) {
  if (run_command("command -v xvfb-run > /dev/null") != 0) GTEST_SKIP() << "xvfb-run is not installed";
  const std::string dir = output_dir("cmd_run_demo_window");
  std::string out;
  ASSERT_EQ(run_command("xvfb-run -a " + augrig_binary() + " demo --out " + dir +
                            " --every 15 --duration 4 --record " + dir +
                            "/recording --receiver-draw wireframe --screenshot-at 3 2>&1",
                        &out),
            0)
      << out;
  EXPECT_TRUE(contains(out, "the flight in real time in the live window")) << out;
  EXPECT_TRUE(contains(out, "poses from the live nav")) << out;
  EXPECT_TRUE(contains(out, "live display open")) << out;
  EXPECT_TRUE(contains(out, "recorded ")) << out;
  std::string check;
  EXPECT_EQ(augrig("check " + dir + "/recording", &check), 0) << check;
  {
    // The window showed the boom where the recorded masks of the pair shown say.
    const auto shot = test::parse_window_shot(out);
    ASSERT_TRUE(shot) << out;
    auto reader = recorder::RecordingReader::open(dir + "/recording");
    ASSERT_TRUE(reader) << reader.error().message;
    auto f = (*reader)->read_frame(shot->pair - 1);
    ASSERT_TRUE(f) << f.error().message;
    test::check_window_shot(*shot, *f);
  }
  // Again into the same --out, without --record: no recording is made, and nothing refuses; a
  // second recording into the same folder needs --overwrite and says so.
  ASSERT_EQ(run_command("xvfb-run -a " + augrig_binary() + " demo --out " + dir +
                            " --every 15 --duration 30 --frames 3 --bayer 2>&1",
                        &out),
            0)
      << out;
  EXPECT_FALSE(contains(out, "recorded ")) << out;
  EXPECT_TRUE(contains(out, "bayer=RG")) << out;  // --bayer reaches the simulated cameras
  EXPECT_TRUE(contains(out, "run: 3 stereo frames augmented")) << out;  // --frames: stop after 3
  EXPECT_EQ(run_command("xvfb-run -a " + augrig_binary() + " demo --out " + dir +
                            " --every 15 --duration 2 --record " + dir + "/recording 2>&1",
                        &out),
            1)
      << out;
  EXPECT_TRUE(contains(out, "a recording is already there; give --overwrite")) << out;
  // No display: the batch demo refuses the window-only flag.
  EXPECT_EQ(augrig("demo --out " + dir + "/batch --headless --duration 4", &out), 2) << out;
}

// The window of `augrig run` under Xvfb: the screenshot of a shown pair has both views, the boom
// where the recorded masks of that very pair say, and the occlusion panel filled.
TEST(CmdRun, WindowScreenshotShowsTheBoomWhereTheMasksSay) {
  if (run_command("command -v xvfb-run > /dev/null") != 0) GTEST_SKIP() << "xvfb-run is not installed";
  const std::string dir = output_dir("cmd_run_window_shot");
  std::string out;
  ASSERT_EQ(run_command(
                "xvfb-run -a " + augrig_binary() + " run --source 'sim://demo?every=30&rate=0' --frames 4 " +
                    "--screenshot-at 2 --status-every 0 --out " + dir + " --record " + dir + "/rec 2>&1",
                &out),
            0)
      << out;
  const auto shot = test::parse_window_shot(out);
  ASSERT_TRUE(shot) << out;
  auto reader = recorder::RecordingReader::open(dir + "/rec");
  ASSERT_TRUE(reader) << reader.error().message;
  ASSERT_GE(shot->pair, 1u);
  auto frame = (*reader)->read_frame(shot->pair - 1);
  ASSERT_TRUE(frame) << frame.error().message;
  test::check_window_shot(*shot, *frame);
}

// Frames whose size is not the rig's: the run fails at the first frame, once, naming both sizes,
// and nothing is augmented (it used to print one error per frame and exit 0 with "0 pairs").
// A rig without a boom section captures only: the run records the raw frames with the simulation's
// poses and augments nothing, flags that need augmenting are refused, the recording cannot be
// augmented with its own rig, and a rig with a boom augments it from the poses the export wrote.
TEST(CmdRun, CaptureOnlyRigRecordsRawThenAReplayAugmentsIt) {
  const std::string dir = output_dir("cmd_run_capture_only");
  fs::remove_all(dir);
  fs::create_directories(dir);
  Rig capture = Rig::paper_default();
  capture.boom.configured = false;
  std::ofstream(dir + "/capture.yaml") << rig_to_yaml(capture);
  std::ofstream(dir + "/full.yaml") << rig_to_yaml(Rig::paper_default());
  const std::string src = " --source 'sim://demo?rate=0&every=45' --headless --status-every 0";
  std::string out;
  ASSERT_EQ(augrig("run --rig " + dir + "/capture.yaml" + src + " --record " + dir + "/rec", &out), 0) << out;
  EXPECT_TRUE(contains(out, "capture only (nothing augmented)")) << out;
  EXPECT_TRUE(contains(out, "stereo frames captured (not augmented)")) << out;
  const auto acc = frame_account(out);
  ASSERT_TRUE(acc) << out;
  EXPECT_EQ(acc->left + acc->right, 2 * acc->pairs + acc->unpaired + acc->queue + acc->pending) << out;
  ASSERT_GT(acc->pairs, 5u);
  auto reader = recorder::RecordingReader::open(dir + "/rec");
  ASSERT_TRUE(reader) << reader.error().message;
  const std::size_t frames = (*reader)->frame_count();
  EXPECT_EQ(frames, acc->pairs);
  {
    auto f = (*reader)->read_frame(0);
    ASSERT_TRUE(f) << f.error().message;
    EXPECT_TRUE(f->augmented[0].empty() && f->mask[0].empty() && !f->stats);
    EXPECT_TRUE(f->T_cam_receiver[0].has_value());
  }
  // The same with --capture-only and any rig; flags that need augmenting are refused.
  EXPECT_EQ(augrig("run --rig " + dir + "/capture.yaml" + src + " --out " + dir + "/o", &out), 2) << out;
  EXPECT_TRUE(contains(out, "--out: nothing is augmented when capturing only")) << out;
  EXPECT_TRUE(contains(out, "has no boom section: a capture-only rig")) << out;
  EXPECT_EQ(augrig("run --capture-only" + src + " --boom track", &out), 2) << out;
  EXPECT_TRUE(contains(out, "--boom: nothing is augmented when capturing only (--capture-only)")) << out;
  // Replayed with its own (capture-only) rig: refused, saying why and what to give.
  EXPECT_EQ(augrig("replay " + dir + "/rec --headless", &out), 1) << out;
  EXPECT_TRUE(contains(out, "no boom section: a capture-only rig")) << out;
  EXPECT_TRUE(contains(out, "give one with --rig")) << out;
  // The export's poses.csv (the recorded T_cam_receiver) and a rig with a boom: augmented.
  ASSERT_EQ(augrig("export " + dir + "/rec " + dir + "/x --no-plot", &out), 0) << out;
  ASSERT_EQ(augrig("replay " + dir + "/rec --rig " + dir + "/full.yaml --poses " + dir +
                       "/x/poses.csv --record " + dir + "/rec2 --headless",
                   &out),
            0)
      << out;
  auto again = recorder::RecordingReader::open(dir + "/rec2");
  ASSERT_TRUE(again) << again.error().message;
  ASSERT_EQ((*again)->frame_count(), frames) << out;
  for (std::size_t i = 0; i < frames; ++i) {
    auto f = (*again)->read_frame_info(i);
    ASSERT_TRUE(f && f->stats) << i;
    EXPECT_GT(f->stats->boom_px_left, 0) << i;
    EXPECT_GT(f->stats->receiver_px_left, 0) << i;
  }
  // --poses and --scene are two sources of poses.
  EXPECT_EQ(augrig("replay " + dir + "/rec --poses " + dir + "/x/poses.csv --scene " + dir + "/s.yaml", &out),
            2)
      << out;
}

// run --serve: the live view over the network while the real binary runs. A WebSocket client on
// loopback gets the Foxglove protocol's serverInfo and advertise, subscribes, and decodes (with
// the ROS 2 decoders, as Foxglove would with the advertised schemas) the augmented images, the
// statistics, the health and the right augmented view's H.264 stream (FFmpeg's decoder, from its
// first unit) while the run goes on; the summary counts the client and what it got.
TEST(CmdRun, ServesTheLiveViewOverFoxgloveWebSocket) {
  const std::string dir = output_dir("cmd_run_serve");
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string log = dir + "/run.log";
  ASSERT_EQ(std::system(("(" + augrig_binary() +
                         " run --source 'sim://demo?rate=1&every=3' --headless --status-every 0 --duration " +
                         std::to_string(test::kSanitized ? 30 : 12) +
                         " --serve 0 "
                         "--serve-h264-preset superfast > " +
                         log + " 2>&1; echo $? > " + dir + "/rc) &")
                            .c_str()),
            0);
  // The port it took, from its first lines.
  int port = 0;
  for (int i = 0; i < 300 && !port; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    std::ifstream in(log);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    static const std::regex re("live view: ws://127\\.0\\.0\\.1:([0-9]+)");
    std::smatch m;
    if (std::regex_search(text, m, re)) port = std::stoi(m[1]);
  }
  ASSERT_GT(port, 0) << "no 'live view: ws://127.0.0.1:PORT' line";
  test::TestWsClient c(port);
  ASSERT_TRUE(c.connected());
  const std::string head = c.handshake("foxglove.websocket.v1");
  ASSERT_NE(head.find("101"), std::string::npos) << head;
  std::map<std::string, std::uint32_t> channel;
  for (int i = 0; i < 2; ++i) {
    auto f = c.read_frame();
    ASSERT_TRUE(f && f->opcode == 0x1);
    const nlohmann::json j = nlohmann::json::parse(f->payload);
    if (j["op"] == "advertise")
      for (const auto& ch : j["channels"])
        channel[ch["topic"].get<std::string>()] = ch["id"].get<std::uint32_t>();
  }
  for (const char* t :
       {"/left/image_augmented", "/augrig/occlusion_stats", "/diagnostics", "/right/mask", "/tf"})
    ASSERT_TRUE(channel.count(t)) << t;
  nlohmann::json sub = {{"op", "subscribe"},
                        {"subscriptions",
                         {{{"id", 1}, {"channelId", channel["/left/image_augmented"]}},
                          {{"id", 2}, {"channelId", channel["/augrig/occlusion_stats"]}},
                          {{"id", 3}, {"channelId", channel["/diagnostics"]}},
                          {{"id", 4}, {"channelId", channel["/right/image_augmented/h264"]}}}}};
  ASSERT_TRUE(c.send_text(sub.dump()));
  std::map<std::uint32_t, int> got;
  std::int64_t last_image_ns = 0;
  std::string health;
  std::map<std::string, std::string> health_values;
  auto decoder = H264Decoder::create();
  ASSERT_TRUE(decoder);
  // 3 s from the first message (the run may still be starting: its GL context, the flight); 12 s
  // under a sanitizer, whose build augments a pair a second.
  std::optional<std::chrono::steady_clock::time_point> until;
  while (!until || std::chrono::steady_clock::now() < *until) {
    auto f = c.read_frame(until ? 2000 : 8000);
    ASSERT_TRUE(f) << "the server went quiet";
    if (!until) until = std::chrono::steady_clock::now() + std::chrono::seconds(3 * test::kSlowdown);
    if (f->opcode != 0x2) continue;
    ASSERT_GE(f->payload.size(), 13u);
    ASSERT_EQ(static_cast<unsigned char>(f->payload[0]), 0x01) << "Message Data";
    std::uint32_t sid = 0;
    std::memcpy(&sid, f->payload.data() + 1, 4);
    const std::vector<std::uint8_t> msg(f->payload.begin() + 13, f->payload.end());
    ++got[sid];
    if (sid == 1) {
      std::int64_t stamp = 0;
      auto im = ros2::decode_image(msg, &stamp);
      ASSERT_TRUE(im) << im.error().message;
      EXPECT_EQ(im->width(), 1280);
      EXPECT_EQ(im->height(), 960);
      EXPECT_GT(stamp, last_image_ns);
      last_image_ns = stamp;
    } else if (sid == 2) {
      auto st = ros2::decode_occlusion_stats(msg);
      ASSERT_TRUE(st) << st.error().message;
      EXPECT_GT(st->boom_px_left, 0);
    } else if (sid == 3) {
      auto d = ros2::decode_diagnostic_array(msg);
      ASSERT_TRUE(d) << d.error().message;
      ASSERT_FALSE(d->empty());
      health = d->front().message;
      for (const auto& [k, v] : d->front().values) health_values[k] = v;
    } else if (sid == 4) {
      auto v = ros2::decode_compressed_video(msg);
      ASSERT_TRUE(v) << v.error().message;
      auto pic = (*decoder)->decode(v->data.data(), v->data.size(), 1280, 960);
      ASSERT_TRUE(pic) << "H.264 unit " << got[4] << ": " << pic.error().message;
      EXPECT_EQ(pic->width(), 1280);
    }
  }
  // Up to 10 pairs a second for 3 s; a loaded machine's simulated cameras lose late frames.
  EXPECT_GE(got[1], 5);
  EXPECT_GE(got[2], 5);
  EXPECT_GE(got[3], 2) << "the health once a second";
  EXPECT_NE(health.find("pairs/s; cameras streaming"), std::string::npos) << health;
  EXPECT_GE(got[4], 3) << "H.264 units";
  EXPECT_TRUE(health_values.count("h264_encoded") && health_values.count("drops_h264"));
  c.close();
  for (int i = 0; i < 400 * test::kSlowdown && !fs::exists(dir + "/rc"); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  std::ifstream rc(dir + "/rc");
  int code = -1;
  rc >> code;
  EXPECT_EQ(code, 0);
  std::ifstream in(log);
  const std::string out((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_TRUE(contains(out, "live view (ws://127.0.0.1:" + std::to_string(port) + "): 1 client(s)")) << out;
  EXPECT_TRUE(contains(out, "live view H.264: ")) << out;
  // Flags: a bad address, a port in use.
  std::string err;
  EXPECT_EQ(augrig("run --source 'sim://demo?rate=0' --headless --serve :x", &err), 2) << err;
  EXPECT_EQ(augrig("run --source 'sim://demo?rate=0' --headless --serve-queue-mb 4", &err), 2) << err;
  EXPECT_EQ(augrig("run --source 'sim://demo?rate=0' --headless --serve-h264-kbps 4000", &err), 2) << err;
  EXPECT_TRUE(contains(err, "--serve-h264-kbps needs --serve")) << err;
  EXPECT_EQ(augrig("run --source 'sim://demo?rate=0' --headless --serve 0 --serve-h264-preset quick", &err),
            2)
      << err;
  EXPECT_TRUE(contains(err, "--serve-h264-preset: expected one of ultrafast, superfast")) << err;
  EXPECT_TRUE(contains(err, "got 'quick'")) << err;
  EXPECT_EQ(augrig("run --source 'sim://demo?rate=0' --headless --frames 1 --serve 256.1.1.1:0", &err), 1)
      << err;
}

TEST(CmdRun, FrameSizeNotTheRigsFailsAtOnce) {
  const std::string dir = output_dir("cmd_run_size_mismatch");
  Rig small = Rig::paper_default();
  for (RigCamera& c : small.cameras) c.model = CameraModel::pinhole_from_hfov(640, 480, deg_to_rad(56.0));
  {
    std::ofstream f(dir + "/small.yaml");
    f << rig_to_yaml(small);
  }
  std::string out;
  EXPECT_EQ(augrig("run --source 'sim://demo?rate=0&every=30' --rig " + dir +
                       "/small.yaml --headless --record " + dir + "/rec",
                   &out),
            1)
      << out;
  EXPECT_TRUE(contains(out, "the left image is 1280x960, the rig's left camera is 640x480")) << out;
  EXPECT_EQ(out.find("the left image is"), out.rfind("the left image is")) << "one message\n" << out;
  EXPECT_FALSE(contains(out, "stereo frames augmented")) << out;
}

// A model file that cannot be read fails the run before anything is opened or created: no
// recording folder is left behind to be refused by the next run without --overwrite.
TEST(CmdRun, UnreadableModelFailsBeforeTheRecordingIsCreated) {
  const std::string dir = output_dir("cmd_run_bad_model");
  std::ofstream(dir + "/broken.glb") << "not a glTF file";
  for (const char* part : {"boom", "receiver"}) {
    Rig rig = Rig::paper_default();
    (std::string(part) == "boom" ? rig.boom.model : rig.receiver.model).path = dir + "/broken.glb";
    const std::string rig_file = dir + "/" + part + ".yaml";
    std::ofstream(rig_file) << rig_to_yaml(rig);
    const std::string rec = dir + "/rec_" + part;
    std::string out;
    EXPECT_EQ(
        augrig("run --source 'sim://demo?rate=0&every=30' --rig " + rig_file + " --headless --record " + rec,
               &out),
        1)
        << out;
    EXPECT_TRUE(contains(out, std::string(part) + " model: ")) << out;
    EXPECT_TRUE(contains(out, dir + "/broken.glb")) << out;
    EXPECT_FALSE(fs::exists(rec)) << part << ": " << out;
  }
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
           {"run --source 'sim://demo' --nav-fault receiver.gps=1-2", 2, "--nav-fault needs --nav sim"},
           {"run --source 'sim://demo' --nav sim --nav-fault receiver.gps=abc", 2, "expected STREAM=T0-T1"},
           {"run --source 'sim://demo' --nav sim --nav-fault ground.gps=1-2", 2, "no stream 'ground.gps'"},
           {"run --source 'sim://demo' --nav sim --aircraft foo=bar", 2,
            "expected tanker=FILE or receiver=FILE"},
           {"run --source 'sim://demo' --nav sim --aircraft tanker=/nonexistent.yaml", 1,
            "/nonexistent.yaml"},
           {"run --source 'sim://demo' --nav sim --nav-stale 0", 2, "--nav-stale: expected seconds > 0"},
           {"run --source 'sim://demo' --nav sim --camera-clock maybe", 2,
            "--camera-clock: expected online or off, got 'maybe'"},
           {"run --source 'sim://demo' --camera-clock online", 2, "--camera-clock online needs the live nav"},
           {"run --source 'sim://demo' --nav sim --camera-clock-sigma-ms 1", 2,
            "--camera-clock-sigma-ms and --terrain-height-m need --camera-clock online"},
           {"run --source 'sim://demo' --nav sim --camera-clock online --camera-clock-sigma-ms 0", 2,
            "--camera-clock-sigma-ms: expected milliseconds in (0, 100]"},
           {"run --source 'replay:///nonexistent/rec' --nav sim", 1, "/nonexistent/rec"},
           // No pose source for cameras or a dataset: refused before anything is opened.
           {"run --source 'stereo://{aravis://a}{aravis://b}'", 2, "a pose source is needed"},
           {"run --source 'euroc:///nonexistent'", 2, "--scene SCENE.yaml, --poses POSES.csv, or --nav"},
           {"run --source 'sim://demo'" + scene + " --poses /x.csv", 2, "three sources of poses: give one"},
       }) {
    std::string out;
    EXPECT_EQ(augrig(c.args, &out), c.code) << c.args << "\n" << out;
    EXPECT_TRUE(contains(out, c.message)) << c.args << "\n" << out;
    EXPECT_TRUE(contains(out, "augrig run: ")) << out;
  }
}

}  // namespace
}  // namespace augrig
