#include "tests/support/recording_fixture.hpp"

#include <fstream>
#include <map>
#include <memory>
#include <random>

#include <gtest/gtest.h>

#include "recorder/recorder.hpp"
#include "render/augmenter.hpp"
#include "render/gl_context.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::test {

Rig small_rig() {
  Rig rig = Rig::paper_default();
  for (RigCamera& c : rig.cameras) c.model = CameraModel::pinhole_from_hfov(128, 96, deg_to_rad(56.0));
  return *parse_rig(rig_to_yaml(rig), "<string>");
}

Image raw_image(int i, int c) {
  Image im(128, 96, PixelFormat::kMono8);
  std::mt19937 rng(static_cast<unsigned>(10 * i + c));
  for (int y = 0; y < im.height(); ++y)
    for (int x = 0; x < im.width(); ++x) im.row(y)[x] = static_cast<std::uint8_t>(x + y + rng() % 16);
  return im;
}

std::string write_recording(const std::string& dir, int frames) {
  const Rig rig = small_rig();
  auto ctx = create_gl_context(GlBackend::kEglHeadless);
  EXPECT_TRUE(ctx) << ctx.error().message;
  Eigen::Vector3d receptacle;
  AugmentOptions options;
  options.receiver_model = std::make_shared<const Model>(make_builtin_receiver(&receptacle));
  auto augmenter = Augmenter::create(rig, options);
  EXPECT_TRUE(augmenter) << augmenter.error().message;
  recorder::RecordingInfo info;
  info.rig_yaml = rig_to_yaml(rig);
  auto rec = recorder::Recorder::create(dir, info);
  EXPECT_TRUE(rec) << rec.error().message;
  StereoResult result;
  for (int i = 0; i < frames; ++i) {
    recorder::FrameRecord r;
    r.raw.pair_sequence = static_cast<std::uint64_t>(i);
    r.raw.t_key_ns = kRecordingT0 + i * kRecordingPeriod;
    for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
      Frame& f = r.raw[id];
      f.camera = id;
      f.t_ns = r.raw.t_key_ns;
      f.clock = ClockDomain::kSim;
      f.sequence = static_cast<std::uint64_t>(i);
      f.image = raw_image(i, index_of(id));
    }
    const BoomArticulation a{deg_to_rad(26.0 + i % 8), deg_to_rad(i % 8 - 4.0), 1.0 + 0.3 * (i % 8)};
    const SceneState scene =
        scene_at_contact(rig, BoomDimensions{}, receptacle, a, Eigen::Vector3d(0, 0, 0.5));
    EXPECT_TRUE((*augmenter)->augment(r.raw, scene, result));
    result.stats.t_ns = r.raw.t_key_ns;
    for (int c = 0; c < 2; ++c) {
      const ViewResult& v = c == 0 ? result.left : result.right;
      r.augmented[c] = v.augmented;
      r.mask[c] = v.mask;
      r.T_cam_receiver[c] =
          rig.cameras[static_cast<std::size_t>(c)].T_body_cam.inverse() * scene.T_body_receiver;
    }
    r.T_body_receiver = scene.T_body_receiver;
    r.receiver_present = scene.receiver_present;
    r.boom = scene.boom;
    r.stats = result.stats;
    EXPECT_TRUE((*rec)->push(std::move(r)));
  }
  EXPECT_TRUE((*rec)->close());
  return dir;
}

const std::string& recording_of_this_test(const std::string& prefix, int frames) {
  // Written once per (prefix, frames) in this process; the map never shrinks, so the references
  // handed out stay valid.
  static std::map<std::pair<std::string, int>, std::string> written;
  const auto key = std::make_pair(prefix, frames);
  auto it = written.find(key);
  if (it == written.end()) {
    const std::string dir =
        output_dir(prefix + testing::UnitTest::GetInstance()->current_test_info()->name()) + "/rec";
    it = written.emplace(key, write_recording(dir, frames)).first;
  }
  return it->second;
}

std::string truncated_copy(const std::string& from, const std::string& name, std::uintmax_t bytes) {
  const std::string dir = output_dir(name);
  std::ifstream in(from + "/recording.sqlite", std::ios::binary);
  std::string data(bytes, '\0');
  in.read(data.data(), static_cast<std::streamsize>(bytes));
  data.resize(static_cast<std::size_t>(in.gcount()));
  std::ofstream(dir + "/recording.sqlite", std::ios::binary) << data;
  return dir;
}

}  // namespace augrig::test
