// AravisSource against real GigE Vision peers on loopback: Aravis' fake GV camera in this process
// (serving the simulated flight's own rendered frames) and the arv-fake-gv-camera-0.8 program
// (killed and restarted mid-stream).
#include "capture/aravis_source.hpp"

#include <atomic>
#include <map>
#include <thread>

#include <gtest/gtest.h>

#include "capture/stereo_pairer.hpp"
#include "render/gl_context.hpp"
#include "sim/flight_source.hpp"
#include "tests/support/fake_gv_camera.hpp"

namespace augrig {
namespace {

using namespace std::chrono_literals;
using test::FakeGvCamera;
using test::ServedFrame;

// Rendered frames of the simulated demo flight, one camera, as the camera would stream them.
std::vector<ServedFrame> sim_frames(int camera, int count, PixelFormat format) {
  auto ctx = create_gl_context(GlBackend::kEglHeadless);
  EXPECT_TRUE(ctx) << ctx.error().message;
  sim::Scenario s = *sim::builtin_scenario("demo");
  s.sensors.cameras.format = format;
  s.sensors.cameras.noise_sigma = 2.0;  // sensor noise: no two frames alike
  const sim::Flight f = *sim::Flight::create(s);
  const sim::SensorLogs logs = sim::simulate_sensors(s, f);
  std::vector<sim::FrameTruth> truths = sim::frame_truths(s, f, logs.cameras);
  std::erase_if(truths, [&](const sim::FrameTruth& t) { return t.camera != camera; });
  truths.resize(count);
  auto source = sim::FlightSource::create(s, f, truths);
  EXPECT_TRUE(source) << source.error().message;
  std::vector<ServedFrame> out;
  Frame frame;
  while (out.size() < static_cast<std::size_t>(count) && *(*source)->read(frame, {}) == ReadStatus::kFrame)
    out.push_back({frame.image, static_cast<std::uint64_t>(frame.t_ns)});
  return out;
}

// Reads until `n` frames came (or a deadline), failing on errors.
std::vector<Frame> read_frames(AravisSource& src, std::size_t n, std::chrono::seconds limit = 20s) {
  std::vector<Frame> out;
  const auto until = std::chrono::steady_clock::now() + limit;
  while (out.size() < n && std::chrono::steady_clock::now() < until) {
    Frame f;
    auto r = src.read(f, 200ms);
    EXPECT_TRUE(r) << r.error().message;
    if (!r) break;
    if (*r == ReadStatus::kFrame) out.push_back(std::move(f));
  }
  return out;
}

TEST(AravisSource, FindsTheFakeCameraByAddressSerialAndId) {
  FakeGvCamera fake("127.0.0.1", "AUGID1");
  ASSERT_TRUE(fake.running());
  bool listed = false;
  for (const AravisDeviceInfo& d : list_aravis_devices()) {
    if (d.serial != "AUGID1") continue;
    listed = true;
    EXPECT_EQ(d.address, "127.0.0.1");
    EXPECT_EQ(d.protocol, "GigEVision");
    EXPECT_EQ(d.model, "Fake");
    EXPECT_NE(std::find(d.pixel_formats.begin(), d.pixel_formats.end(), "BayerRG8"), d.pixel_formats.end());
  }
  EXPECT_TRUE(listed) << "discovery did not list the fake camera";
  for (const std::string device : {"127.0.0.1", "AUGID1", "Aravis-Fake-AUGID1"}) {
    AravisOptions o;
    o.device = device;
    auto src = AravisSource::open(o);
    ASSERT_TRUE(src) << device << ": " << src.error().message;
    EXPECT_EQ((*src)->info().serial, "AUGID1") << device;
    EXPECT_EQ((*src)->info().address, "127.0.0.1") << device;
    EXPECT_EQ((*src)->uri(), "aravis://" + device);
    EXPECT_EQ(read_frames(**src, 2).size(), 2u) << device;
  }
}

// The listing reads each camera's current size, pixel format and rate: those a source set.
TEST(AravisSource, ListingShowsTheCamerasCurrentSettings) {
  FakeGvCamera fake("127.0.0.1", "AUGSET");
  ASSERT_TRUE(fake.running());
  {
    AravisOptions o;
    o.device = "AUGSET";
    o.pixel_format = "BayerRG8";
    o.roi = RegionOfInterest{0, 0, 320, 240};
    o.frame_rate_hz = 20.0;
    auto src = AravisSource::open(o);
    ASSERT_TRUE(src) << src.error().message;
  }
  bool listed = false;
  for (const AravisDeviceInfo& d : list_aravis_devices()) {
    if (d.serial != "AUGSET") continue;
    listed = true;
    EXPECT_EQ(d.width_px, 320);
    EXPECT_EQ(d.height_px, 240);
    EXPECT_EQ(d.pixel_format, "BayerRG8");
    EXPECT_NEAR(d.frame_rate_hz, 20.0, 0.01);
  }
  EXPECT_TRUE(listed);
  for (const AravisDeviceInfo& d : list_aravis_devices(false)) {
    if (d.serial == "AUGSET") {
      EXPECT_EQ(d.width_px, 0) << "not opened: nothing read";
    }
  }
}

TEST(AravisSource, UnknownDeviceAndBadOptionsGiveClearErrors) {
  FakeGvCamera fake("127.0.0.1", "AUGERR");
  ASSERT_TRUE(fake.running());
  AravisOptions o;
  o.device = "NO-SUCH-CAMERA";
  auto src = AravisSource::open(o);
  ASSERT_FALSE(src);
  EXPECT_NE(src.error().message.find("aravis://NO-SUCH-CAMERA"), std::string::npos) << src.error().message;
  EXPECT_NE(src.error().message.find("Aravis-Fake-AUGERR"), std::string::npos) << "lists what it found";

  o.device = "127.0.0.1";
  o.pixel_format = "Mono12p";
  src = AravisSource::open(o);
  ASSERT_FALSE(src);
  EXPECT_NE(src.error().message.find("pixel_format 'Mono12p' is not supported"), std::string::npos)
      << src.error().message;

  o.pixel_format = "";
  o.roi = RegionOfInterest{0, 0, 4096, 100};
  src = AravisSource::open(o);
  ASSERT_FALSE(src);
  EXPECT_NE(src.error().message.find("roi 0,0 4096x100 does not fit the sensor"), std::string::npos)
      << src.error().message;
}

// The sim's rendered Bayer frames go over GigE Vision and arrive bit for bit, with their device
// timestamps (moved to mid-exposure), consecutive sequence numbers and nothing dropped.
// A free-running camera starts streaming at the first read(), not at open(): a pipeline that opens
// its cameras and then spends a while setting up must not find Aravis' buffers overrun (frames lost
// as frame id gaps) and a burst of stale frames waiting.
TEST(AravisSource, FreeRunningCameraStartsAtTheFirstRead) {
  FakeGvCamera fake("127.0.0.1", "AUGLATE");
  ASSERT_TRUE(fake.running());
  AravisOptions o;
  o.device = "127.0.0.1";
  o.frame_rate_hz = 30;
  auto src = AravisSource::open(o);
  ASSERT_TRUE(src) << src.error().message;
  std::this_thread::sleep_for(1500ms);  // 45 frame periods: far more than the buffers hold
  const std::vector<Frame> got = read_frames(**src, 10);
  ASSERT_EQ(got.size(), 10u);
  const AravisStats st = (*src)->stats();
  // No stale burst: the frames follow on, one period apart on the camera's clock. A loopback
  // packet lost in a loaded CTest run (the socket's buffer overruns while the stream thread waits
  // for a core) loses its frame: counted as a transport drop, leaving a gap of one.
  std::uint64_t gaps = 0;
  for (std::size_t k = 1; k < got.size(); ++k) {
    ASSERT_GT(got[k].sequence, got[k - 1].sequence);
    gaps += got[k].sequence - got[k - 1].sequence - 1;
  }
  EXPECT_LE(gaps, st.transport_drops) << "every frame missing was lost in transport, counted";
  EXPECT_LE(st.transport_drops, 2u);
  const auto periods = static_cast<std::int64_t>(got.back().sequence - got.front().sequence);
  EXPECT_LT(got.back().t_ns - got.front().t_ns, periods * 33'333'333 + 20'000'000);
  EXPECT_EQ(st.camera_drops, 0u) << "a frame lost in transport is not also a camera drop";
  EXPECT_EQ(st.underruns, 0u);
}

// Packets lost on the link lose their frames: each is counted once, as a transport drop, and the
// frame id gap it leaves is not counted again as a frame the camera dropped; the frames that do
// arrive are whole and follow on by their ids.
TEST(AravisSource, PacketsLostOnTheLinkAreTransportDropsCountedOnce) {
  FakeGvCamera fake("127.0.0.1", "AUGLOSS");
  ASSERT_TRUE(fake.running());
  fake.set_lost_packet_ratio(0.002);  // 0.2 %: about a quarter of the frames lose a packet
  AravisOptions o;
  o.device = "127.0.0.1";
  o.frame_rate_hz = 30;
  auto src = AravisSource::open(o);
  ASSERT_TRUE(src) << src.error().message;
  const std::vector<Frame> first = read_frames(**src, 1);
  ASSERT_EQ(first.size(), 1u);
  const AravisStats before = (*src)->stats();
  const std::vector<Frame> got = read_frames(**src, 40);
  ASSERT_EQ(got.size(), 40u);
  const AravisStats st = (*src)->stats();
  std::uint64_t gaps = got.front().sequence - first.front().sequence - 1;
  for (std::size_t k = 1; k < got.size(); ++k) {
    ASSERT_GT(got[k].sequence, got[k - 1].sequence);
    gaps += got[k].sequence - got[k - 1].sequence - 1;
  }
  EXPECT_GT(st.transport_drops, before.transport_drops) << "the link lost no frame: the test shows nothing";
  EXPECT_EQ(gaps, st.transport_drops - before.transport_drops) << "each missing frame is a transport drop";
  EXPECT_EQ(st.camera_drops, 0u) << "a frame lost on the link is not also a camera drop";
  EXPECT_EQ((*src)->frames_dropped(), st.transport_drops);
  for (const Frame& f : got) EXPECT_FALSE(f.image.empty());
}

TEST(AravisSource, StreamsSimulatedFlightFramesBitExact) {
  const std::vector<ServedFrame> sent = sim_frames(0, 6, PixelFormat::kBayerRG8);
  ASSERT_EQ(sent.size(), 6u);
  FakeGvCamera fake("127.0.0.1", "AUGSIM");
  ASSERT_TRUE(fake.running());
  fake.serve(sent);
  AravisOptions o;
  o.device = "127.0.0.1";
  o.pixel_format = "BayerRG8";
  o.roi = RegionOfInterest{0, 0, 1280, 960};
  o.frame_rate_hz = 20;
  o.exposure_us = 4000;
  auto src = AravisSource::open(o);
  ASSERT_TRUE(src) << src.error().message;
  const AravisCameraInfo info = (*src)->info();
  EXPECT_EQ(info.width, 1280);
  EXPECT_EQ(info.height, 960);
  EXPECT_EQ(info.pixel_format, "BayerRG8");
  EXPECT_NEAR(info.frame_rate_hz, 20, 0.5);
  EXPECT_GT(info.packet_size, 576) << "negotiated";

  std::map<std::uint64_t, std::size_t> by_stamp;
  for (std::size_t i = 0; i < sent.size(); ++i) by_stamp[sent[i].timestamp_ns] = i;
  const std::vector<Frame> got = read_frames(**src, 10);
  ASSERT_EQ(got.size(), 10u);
  std::size_t matched = 0;
  for (std::size_t k = 0; k < got.size(); ++k) {
    const Frame& f = got[k];
    EXPECT_EQ(f.clock, ClockDomain::kDevice);
    EXPECT_EQ(f.exposure_ns, 4'000'000);
    EXPECT_GT(f.t_host_ns, 0);
    if (k > 0) {
      EXPECT_EQ(f.sequence, got[k - 1].sequence + 1) << "no frame skipped";
    }
    // The fake stamps each frame it serves; the first frames may predate serve().
    const auto it = by_stamp.find(static_cast<std::uint64_t>(f.t_ns - 2'000'000));
    if (it == by_stamp.end()) continue;
    ++matched;
    EXPECT_EQ(f.image.format(), PixelFormat::kBayerRG8);
    EXPECT_TRUE(pixels_equal(f.image, sent[it->second].image)) << "frame " << it->second << " differs";
  }
  EXPECT_GE(matched, 8u);
  const AravisStats st = (*src)->stats();
  EXPECT_EQ(st.frames, 10u);
  EXPECT_EQ(st.camera_drops, 0u);
  // Loopback UDP in a loaded CTest run can lose a packet (the socket's buffer overruns while the
  // stream thread waits for a core; seen once in a fresh-clone CI beside the npm client test): the
  // frame is counted, never delivered damaged (every frame above is bit-exact).
  EXPECT_LE(st.transport_drops, 2u);
  EXPECT_GE((*src)->frames_dropped(), st.transport_drops);  // counted (read later: never fewer)
  EXPECT_TRUE((*src)->health().connected);
}

// Each format the fake camera offers arrives as the matching 8-bit image; Mono16 keeps its top byte.
TEST(AravisSource, DeliversEachPixelFormat) {
  FakeGvCamera fake("127.0.0.1", "AUGFMT");
  ASSERT_TRUE(fake.running());
  struct Case {
    const char* name;
    PixelFormat sent_as;
    int bytes;
    PixelFormat expect;
  };
  for (const Case c : {Case{"Mono8", PixelFormat::kMono8, 1, PixelFormat::kMono8},
                       Case{"RGB8", PixelFormat::kRGB8, 3, PixelFormat::kRGB8},
                       Case{"BayerGB8", PixelFormat::kBayerGB8, 1, PixelFormat::kBayerGB8},
                       Case{"Mono16", PixelFormat::kMono8, 2, PixelFormat::kMono8}}) {
    SCOPED_TRACE(c.name);
    const int w = 320, h = 240;
    // A pattern in the camera's own byte layout (Mono16: little-endian 16-bit samples).
    Image img(w * c.bytes, h, PixelFormat::kMono8);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w * c.bytes; ++x)
        img.row(y)[x] = static_cast<std::uint8_t>((x * 7 + y * 13) ^ (x >> 3));
    fake.serve({{img, 1'000'000'000}}, 33'000'000);
    AravisOptions o;
    o.device = "127.0.0.1";
    o.pixel_format = c.name;
    o.roi = RegionOfInterest{0, 0, w, h};
    auto src = AravisSource::open(o);
    ASSERT_TRUE(src) << src.error().message;
    const std::vector<Frame> got = read_frames(**src, 4);
    ASSERT_EQ(got.size(), 4u);
    const Frame& f = got.back();
    ASSERT_EQ(f.image.format(), c.expect);
    ASSERT_EQ(f.image.width(), w);
    ASSERT_EQ(f.image.height(), h);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w * (c.bytes == 3 ? 3 : 1); ++x) {
        const std::uint8_t expect = c.bytes == 2 ? img.row(y)[2 * x + 1] : img.row(y)[x];
        ASSERT_EQ(f.image.row(y)[x], expect) << "at " << x << "," << y;
      }
    }
  }
}

TEST(AravisSource, SoftwareTriggerGivesOneFramePerTrigger) {
  FakeGvCamera fake("127.0.0.1", "AUGTRG");
  ASSERT_TRUE(fake.running());
  AravisOptions o;
  o.device = "127.0.0.1";
  o.trigger = TriggerMode::kSoftware;
  o.roi = RegionOfInterest{0, 0, 256, 256};
  auto src = AravisSource::open(o);
  ASSERT_TRUE(src) << src.error().message;
  Frame f;
  auto r = (*src)->read(f, 300ms);
  ASSERT_TRUE(r);
  EXPECT_EQ(*r, ReadStatus::kTimeout) << "no trigger, no frame";
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE((*src)->software_trigger());
    EXPECT_EQ(read_frames(**src, 1, 5s).size(), 1u);
    r = (*src)->read(f, 150ms);
    ASSERT_TRUE(r);
    EXPECT_EQ(*r, ReadStatus::kTimeout) << "exactly one frame per trigger";
  }
  EXPECT_TRUE((*src)->health().connected);
  EXPECT_EQ((*src)->stats().frames, 3u);

  src = make_error("released");  // the camera takes one controller at a time

  // A hardware line trigger: configured, no frame without an edge, and no false loss meanwhile.
  AravisOptions line = o;
  line.trigger = TriggerMode::kLine;
  line.trigger_line = "Line0";
  line.ptp = true;  // the fake camera has no PTP: a note, not an error
  auto src_line = AravisSource::open(line);
  ASSERT_TRUE(src_line) << src_line.error().message;
  for (int i = 0; i < 8; ++i) {
    r = (*src_line)->read(f, 100ms);
    ASSERT_TRUE(r);
    EXPECT_EQ(*r, ReadStatus::kTimeout);
  }
  EXPECT_TRUE((*src_line)->health().connected);
  EXPECT_FALSE((*src_line)->info().ptp);
  ASSERT_EQ((*src_line)->info().notes.size(), 1u);
  EXPECT_NE((*src_line)->info().notes[0].find("ptp requested"), std::string::npos);
  src_line = make_error("released");
  AravisOptions free_run = o;
  free_run.trigger = TriggerMode::kFreeRun;
  auto src2 = AravisSource::open(free_run);
  ASSERT_TRUE(src2) << src2.error().message;
  EXPECT_FALSE((*src2)->software_trigger()) << "only in software trigger mode";
}

// Two cameras on two loopback addresses: the sim's left and right frames arrive bit for bit and
// pair by their device timestamps.
TEST(AravisSource, StereoFromTwoCamerasPairsBitExact) {
  std::string why;
  if (!test::ensure_loopback_address("127.0.0.2", &why)) GTEST_SKIP() << why;
  const std::vector<ServedFrame> left = sim_frames(0, 4, PixelFormat::kBayerRG8);
  const std::vector<ServedFrame> right = sim_frames(1, 4, PixelFormat::kBayerRG8);
  FakeGvCamera fake_l("127.0.0.1", "AUGL");
  FakeGvCamera fake_r("127.0.0.2", "AUGR");
  ASSERT_TRUE(fake_l.running());
  ASSERT_TRUE(fake_r.running());
  // One lap of 4 frames at 30 fps.
  fake_l.serve(left, 4 * 33'333'333);
  fake_r.serve(right, 4 * 33'333'333);
  AravisOptions o;
  o.pixel_format = "BayerRG8";
  o.roi = RegionOfInterest{0, 0, 1280, 960};
  o.frame_rate_hz = 15;
  o.device = "AUGL";
  auto src_l = AravisSource::open(o);
  ASSERT_TRUE(src_l) << src_l.error().message;
  o.device = "127.0.0.2";
  o.camera = CameraId::kRight;
  auto src_r = AravisSource::open(o);
  ASSERT_TRUE(src_r) << src_r.error().message;
  EXPECT_EQ((*src_r)->info().address, "127.0.0.2");

  // Each camera read on its own thread, as the live pipeline does.
  std::vector<Frame> got_l, got_r;
  std::thread tl([&] { got_l = read_frames(**src_l, 12); });
  std::thread tr([&] { got_r = read_frames(**src_r, 12); });
  tl.join();
  tr.join();
  ASSERT_EQ(got_l.size(), 12u);
  ASSERT_EQ(got_r.size(), 12u);
  StereoPairer pairer(2'000'000, 32);
  std::vector<StereoFrame> pairs;
  std::size_t il = 0, ir = 0;
  while (il < got_l.size() || ir < got_r.size()) {
    const bool take_left = ir >= got_r.size() || (il < got_l.size() && got_l[il].t_ns <= got_r[ir].t_ns);
    auto p = pairer.push(take_left ? got_l[il++] : got_r[ir++]);
    if (p) pairs.push_back(std::move(*p));
  }
  ASSERT_GE(pairs.size(), 6u);
  auto sent_index = [](const std::vector<ServedFrame>& sent, const Frame& f) -> int {
    for (std::size_t i = 0; i < sent.size(); ++i)
      if ((f.t_ns - 5'000'000 - static_cast<std::int64_t>(sent[i].timestamp_ns)) % (4 * 33'333'333) == 0)
        return i;
    return -1;
  };
  int checked = 0;
  for (const StereoFrame& p : pairs) {
    const int i = sent_index(left, p.left), j = sent_index(right, p.right);
    if (i < 0 || j < 0) continue;  // sent before serve() took effect
    EXPECT_EQ(i, j) << "a pair holds the same instant of both cameras";
    EXPECT_TRUE(pixels_equal(p.left.image, left[i].image));
    EXPECT_TRUE(pixels_equal(p.right.image, right[j].image));
    EXPECT_LT(std::abs(p.skew_ns), 2'000'000);
    ++checked;
  }
  EXPECT_GE(checked, 6);
}

// A camera killed mid-stream is reported within 1 s and reconnected once it is back, while the
// other camera keeps streaming on its own thread.
TEST(AravisSource, KilledCameraIsReportedWithinOneSecondAndReconnects) {
  std::string why;
  if (!test::ensure_loopback_address("127.0.0.2", &why)) GTEST_SKIP() << why;
  test::FakeGvProcess proc("127.0.0.1", "AUGKILL");
  ASSERT_TRUE(proc.start()) << "arv-fake-gv-camera-0.8 did not start";
  // The other camera is a process of its own too, as real cameras are: its sending is not starved
  // by this process's threads.
  test::FakeGvProcess other_fake("127.0.0.2", "AUGOTHER");
  ASSERT_TRUE(other_fake.start()) << "arv-fake-gv-camera-0.8 did not start on 127.0.0.2";

  AravisOptions o;
  o.device = "127.0.0.1";
  o.roi = RegionOfInterest{0, 0, 320, 240};
  o.frame_rate_hz = 25;
  // Plain UDP sockets: with Aravis 0.8.26's packet socket, the other camera's stream stopped getting
  // buffers (underruns only) in about 1 run in 4 here while this camera was killed (docs/CAPTURE.md).
  o.packet_socket = false;
  auto src = AravisSource::open(o);
  ASSERT_TRUE(src) << src.error().message;
  o.device = "AUGOTHER";
  o.camera = CameraId::kRight;
  auto other = AravisSource::open(o);
  ASSERT_TRUE(other) << other.error().message;

  std::atomic<bool> stop{false};
  std::atomic<int> other_frames{0};
  std::thread other_reader([&] {
    Frame f;
    while (!stop) {
      auto r = (*other)->read(f, 100ms);
      if (r && *r == ReadStatus::kFrame) other_frames++;
    }
  });

  ASSERT_EQ(read_frames(**src, 5).size(), 5u);
  proc.kill();
  const auto killed = std::chrono::steady_clock::now();
  const int other_before = other_frames.load();
  Frame f;
  while ((*src)->health().connected && std::chrono::steady_clock::now() - killed < 3s) {
    auto r = (*src)->read(f, 50ms);
    ASSERT_TRUE(r) << r.error().message;
  }
  const double detect_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - killed).count();
  const SourceHealth lost = (*src)->health();
  EXPECT_FALSE(lost.connected);
  EXPECT_LT(detect_s, 1.0) << "reported after " << detect_s << " s";
  std::printf("camera loss reported %.3f s after the kill\n", detect_s);
  EXPECT_EQ(lost.disconnects, 1u);
  EXPECT_NE(lost.message.find("left camera (127.0.0.1) lost"), std::string::npos) << lost.message;

  // Down for a while: reads time out, nothing throws, the other camera streams on.
  for (int i = 0; i < 5; ++i) {
    auto r = (*src)->read(f, 100ms);
    ASSERT_TRUE(r);
    EXPECT_EQ(*r, ReadStatus::kTimeout);
  }
  {
    const AravisStats os = (*other)->stats();
    EXPECT_GT(other_frames.load(), other_before + 5)
        << "the other camera went on (its stats: frames " << os.frames << ", transport drops "
        << os.transport_drops << ", camera drops " << os.camera_drops << ", underruns " << os.underruns
        << ", missing packets " << os.missing_packets << ")";
  }
  std::printf("the other camera delivered %d frames during the outage\n", other_frames.load() - other_before);

  ASSERT_TRUE(proc.start());
  const auto restarted = std::chrono::steady_clock::now();
  const std::vector<Frame> after = read_frames(**src, 3, 15s);
  std::printf("frames again %.3f s after the restart\n",
              std::chrono::duration<double>(std::chrono::steady_clock::now() - restarted).count());
  EXPECT_EQ(after.size(), 3u) << "frames again after the restart";
  const SourceHealth back = (*src)->health();
  EXPECT_TRUE(back.connected) << back.message;
  EXPECT_EQ(back.reconnects, 1u);
  EXPECT_NE(back.message.find("reconnected"), std::string::npos) << back.message;
  stop = true;
  other_reader.join();
  EXPECT_TRUE((*other)->health().connected);
  EXPECT_EQ((*other)->health().disconnects, 0u);
}

}  // namespace
}  // namespace augrig
