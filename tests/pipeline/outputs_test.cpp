// pipeline/outputs.hpp on a real Augmenter result (the paper's rig at contact, CPU rasteriser on a
// headless llvmpipe context; whole-image and changed-box outputs). Oracles: the files read back with
// OpenCV (PNG) or parsed here byte by byte (.npy header and data) against the result's own images,
// masks and depth; the visualisations against the seed paper's colours applied here to the masks;
// the true correspondence against a pinhole projection of each left pixel's depth done here; the
// stats.csv header against the column list of README.md; model files missing or present.
#include "pipeline/outputs.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/conventions.hpp"
#include "tests/support/gl_test.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::pipeline {
namespace {

namespace fs = std::filesystem;

bool has(const std::string& s, const std::string& what) {
  return s.find(what) != std::string::npos;
}

// ---------------------------------------------------------------------------------------------
// load_rig_models / receptacle_of: no GL needed.

TEST(LoadRigModels, TheBuiltInReceiverKnowsItsReceptacle) {
  const Rig rig = Rig::paper_default();
  auto m = load_rig_models(rig);
  ASSERT_TRUE(m) << m.error().message;
  ASSERT_TRUE(m->receiver_model);
  EXPECT_GT(m->receiver_model->triangle_count(), 100u);
  EXPECT_FALSE(m->boom_model) << "the built-in boom is the Augmenter's own";
  Eigen::Vector3d receptacle;
  (void)make_builtin_receiver(&receptacle);
  EXPECT_EQ(m->receptacle_m, receptacle);
  EXPECT_EQ(receptacle_of(rig), receptacle);
  // On top of the nose: ahead of the origin and above it (FRD: z up is negative).
  EXPECT_GT(receptacle.x(), 0);
  EXPECT_LT(receptacle.z(), 0);
}

TEST(LoadRigModels, ModelFilesAreLoadedAndTheRigsReceptacleUsed) {
  Rig rig = Rig::paper_default();
  rig.receiver.model.path = test::data_path("models/box.gltf");
  rig.receiver.receptacle_m = Eigen::Vector3d(1.5, 0.25, -0.5);
  rig.boom.model.path = test::data_path("models/box.glb");
  auto m = load_rig_models(rig);
  ASSERT_TRUE(m) << m.error().message;
  ASSERT_TRUE(m->receiver_model);
  EXPECT_EQ(m->receiver_model->triangle_count(), 12u) << "a box: 6 faces of 2 triangles";
  EXPECT_EQ(m->receptacle_m, rig.receiver.receptacle_m);
  EXPECT_EQ(receptacle_of(rig), rig.receiver.receptacle_m);
  ASSERT_TRUE(m->boom_model);
  // box.glb (tests/data/models/make_test_models.py): the box and a one-triangle mesh.
  EXPECT_EQ(m->boom_model->fixed.triangle_count(), 13u);
  EXPECT_EQ(m->boom_model->telescope.triangle_count(), 0u) << "a user boom is one rigid part";
}

TEST(LoadRigModels, AMissingModelFileFailsNamingIt) {
  const std::string missing = test::output_dir("outputs_models") + "/no_such_receiver.glb";
  Rig rig = Rig::paper_default();
  rig.receiver.model.path = missing;
  rig.receiver.receptacle_m = Eigen::Vector3d(1, 0, -1);
  auto m = load_rig_models(rig);
  ASSERT_FALSE(m);
  EXPECT_TRUE(has(m.error().message, missing)) << m.error().message;
  EXPECT_TRUE(has(m.error().message, "receiver model")) << m.error().message;
  // receptacle_of() reads no file.
  EXPECT_EQ(receptacle_of(rig), Eigen::Vector3d(1, 0, -1));

  Rig boom = Rig::paper_default();
  const std::string missing_boom = test::output_dir("outputs_models_boom") + "/no_such_boom.gltf";
  boom.boom.model.path = missing_boom;
  auto b = load_rig_models(boom);
  ASSERT_FALSE(b);
  EXPECT_TRUE(has(b.error().message, missing_boom)) << b.error().message;
  EXPECT_TRUE(has(b.error().message, "boom model")) << b.error().message;

  // A file that is there but is no model.
  Rig broken = Rig::paper_default();
  broken.receiver.model.path = test::data_path("models/broken_json.gltf");
  auto k = load_rig_models(broken);
  ASSERT_FALSE(k);
  EXPECT_TRUE(has(k.error().message, "broken_json.gltf")) << k.error().message;
}

// ---------------------------------------------------------------------------------------------
// StatsCsvWriter.

// The columns as README.md lists them (docs/STATISTICS.md defines them).
const char* kReadmeColumns =
    "t_ns,receiver_px_left,receiver_px_right,boom_px_left,boom_px_right,boom_overlap_px,boom_overlap_pct_"
    "union,"
    "occluded_px_left,occluded_px_right,occluded_pct_left,occluded_pct_right,stereo_both_px,left_only_px,"
    "right_only_px,neither_px,receiver_pct_left,receiver_pct_right,boom_pct_left,boom_pct_right,"
    "shadow_px_left,shadow_px_right,shadow_pct_left,shadow_pct_right";

std::vector<std::string> lines_of(const fs::path& p) {
  std::ifstream in(p);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  return lines;
}

std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> out(1);
  for (char c : line) {
    if (c == ',')
      out.emplace_back();
    else
      out.back() += c;
  }
  return out;
}

TEST(StatsCsvWriter, HeaderAndOneRowPerAddFlushedAsItGoes) {
  const fs::path path = fs::path(test::output_dir("outputs_stats_csv")) / "stats.csv";
  auto w = StatsCsvWriter::create(path);
  ASSERT_TRUE(w) << w.error().message;
  EXPECT_EQ((*w)->path(), path);
  OcclusionStats a;
  a.t_ns = 1401278418001190045;  // more digits than a double holds
  a.width = 1280, a.height = 960;
  a.receiver_px_left = 75082, a.receiver_px_right = 75078;
  a.boom_px_left = 59868, a.boom_px_right = 59936;
  a.boom_overlap_px = 10206;
  a.boom_overlap_pct_union = 9.312213;
  a.occluded_px_left = 12305, a.occluded_px_right = 12198;
  a.occluded_pct_left = 16.388748, a.occluded_pct_right = 16.247;
  a.stereo_both_px = 57707, a.left_only_px = 5070, a.right_only_px = 4613, a.neither_px = 7692;
  a.receiver_pct_left = 6.1102, a.receiver_pct_right = 6.1099;
  a.boom_pct_left = 4.8721, a.boom_pct_right = 4.8776;
  a.shadow_px_left = 4321, a.shadow_px_right = 4302;
  a.shadow_pct_left = 5.755041, a.shadow_pct_right = 5.729508;
  ASSERT_TRUE((*w)->add(a));
  // Flushed per row: the row is in the file while the writer is open.
  std::vector<std::string> lines = lines_of(path);
  ASSERT_EQ(lines.size(), 2u);
  EXPECT_EQ(lines[0], kReadmeColumns);
  OcclusionStats b;
  b.t_ns = 5;
  ASSERT_TRUE((*w)->add(b));
  lines = lines_of(path);
  ASSERT_EQ(lines.size(), 3u);
  const std::vector<std::string> head = split_csv(lines[0]);
  const std::vector<std::string> r = split_csv(lines[1]);
  ASSERT_EQ(r.size(), head.size()) << lines[1];
  ASSERT_EQ(split_csv(lines[2]).size(), head.size()) << lines[2];
  auto col = [&](const std::string& name) {
    for (std::size_t i = 0; i < head.size(); ++i)
      if (head[i] == name) return r[i];
    ADD_FAILURE() << "no column " << name;
    return std::string();
  };
  EXPECT_EQ(col("t_ns"), "1401278418001190045");
  EXPECT_EQ(col("receiver_px_left"), "75082");
  EXPECT_EQ(col("boom_px_right"), "59936");
  EXPECT_EQ(col("boom_overlap_px"), "10206");
  EXPECT_EQ(col("neither_px"), "7692");
  EXPECT_NEAR(std::stod(col("boom_overlap_pct_union")), 9.312213, 0.00005);
  EXPECT_NEAR(std::stod(col("occluded_pct_left")), 16.388748, 0.00005);
  EXPECT_NEAR(std::stod(col("boom_pct_right")), 4.8776, 0.00005);
  EXPECT_EQ(col("shadow_px_left"), "4321");
  EXPECT_EQ(col("shadow_px_right"), "4302");
  EXPECT_NEAR(std::stod(col("shadow_pct_left")), 5.755041, 0.00005);
  EXPECT_NEAR(std::stod(col("shadow_pct_right")), 5.729508, 0.00005);
  EXPECT_EQ(split_csv(lines[2])[0], "5");
}

TEST(StatsCsvWriter, AnUnwritablePathFailsNamingIt) {
  const std::string dir = test::output_dir("outputs_stats_csv_bad");
  const std::string missing = dir + "/no/such/folder/stats.csv";
  auto w = StatsCsvWriter::create(missing);
  ASSERT_FALSE(w);
  EXPECT_TRUE(has(w.error().message, missing)) << w.error().message;
  auto d = StatsCsvWriter::create(dir);  // a folder
  ASSERT_FALSE(d);
  EXPECT_TRUE(has(d.error().message, dir)) << d.error().message;
}

// ---------------------------------------------------------------------------------------------
// A real augmented frame.

struct Augmented {
  Rig rig = Rig::paper_default();
  StereoFrame raw;
  StereoResult whole, box;
};

class OutputsTest : public test::GlTest {
 protected:
  static void SetUpTestSuite() {
    test::GlTest::SetUpTestSuite();
    if (HasFatalFailure()) return;
    auto& a = data();
    a = std::make_unique<Augmented>();
    AugmentOptions opt;
    opt.rasterizer = Rasterizer::kCpu;
    auto augs = test::whole_and_box_augmenters(a->rig, opt);
    ASSERT_TRUE(augs) << augs.error().message;
    Eigen::Vector3d receptacle;
    (void)make_builtin_receiver(&receptacle);
    // Contact, the boom a little off the middle: the boom hides part of the receiver in both views.
    const SceneState scene =
        scene_at_contact(a->rig, augs->whole->boom_model().dims, receptacle, {deg_to_rad(31.0), 0.03, 2.4});
    a->raw.left = test::gradient_frame(a->rig.left().model, PixelFormat::kRGB8, CameraId::kLeft);
    a->raw.right = test::gradient_frame(a->rig.right().model, PixelFormat::kRGB8, CameraId::kRight);
    a->raw.left.t_ns = 1'000'000'000;
    a->raw.right.t_ns = 1'000'000'500;
    ASSERT_TRUE(augs->whole->augment(a->raw, scene, a->whole));
    ASSERT_TRUE(augs->box->augment(a->raw, scene, a->box));
  }
  static void TearDownTestSuite() {
    data().reset();
    test::GlTest::TearDownTestSuite();
  }
  static std::unique_ptr<Augmented>& data() {
    static std::unique_ptr<Augmented> d;
    return d;
  }
  const Augmented& A() const { return *data(); }
};

// The image `raw` with `r.augmented` over it: the whole image, made here from either output form.
cv::Mat expected_bgr(const Image& raw, const ViewResult& v) {
  cv::Mat rgb(raw.height(), raw.width(), CV_8UC3);
  for (int y = 0; y < raw.height(); ++y)
    std::memcpy(rgb.ptr(y), raw.row(y), 3 * static_cast<std::size_t>(raw.width()));
  if (v.augmented.width() == raw.width() && v.augmented.height() == raw.height()) {
    for (int y = 0; y < raw.height(); ++y)
      std::memcpy(rgb.ptr(y), v.augmented.row(y), 3 * static_cast<std::size_t>(raw.width()));
  } else {
    const PixelBox& b = v.augmented_box;
    for (int y = 0; y < b.height(); ++y)
      std::memcpy(rgb.ptr(b.y0 + y) + 3 * b.x0, v.augmented.row(y), 3 * static_cast<std::size_t>(b.width()));
  }
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  return bgr;
}

cv::Mat mask_mat(const Image& m) {
  cv::Mat out(m.height(), m.width(), CV_8UC1);
  for (int y = 0; y < m.height(); ++y) std::memcpy(out.ptr(y), m.row(y), static_cast<std::size_t>(m.width()));
  return out;
}

bool same(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0;
}

// A BGR picture from masks by a rule giving RGB per pixel.
template <typename Rule>
cv::Mat paint(int w, int h, Rule rule) {
  cv::Mat out(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const cv::Vec3b rgb = rule(x, y);
      out.at<cv::Vec3b>(y, x) = cv::Vec3b(rgb[2], rgb[1], rgb[0]);
    }
  return out;
}

const cv::Vec3b kBlack(0, 0, 0), kRed(255, 0, 0), kGreen(0, 255, 0), kBlue(0, 0, 255), kCyan(0, 255, 255),
    kMagenta(255, 0, 255), kWhite(255, 255, 255);

TEST_F(OutputsTest, TheResultHasWhatTheseTestsNeed) {
  const StereoResult& r = A().whole;
  EXPECT_GT(r.stats.receiver_px_left, 1000);
  EXPECT_GT(r.stats.occluded_px_left, 100) << "the boom over the receiver";
  EXPECT_GT(r.stats.boom_overlap_px, 100);
  EXPECT_FALSE(r.stereo_classes.empty());
  EXPECT_FALSE(A().box.left.augmented_box.empty());
  EXPECT_LT(A().box.left.augmented.width(), 1280) << "the changed box only";
}

TEST_F(OutputsTest, FrameImagesAreWrittenWhereTheLayoutSaysAndDecodeToTheResult) {
  for (int form = 0; form < 2; ++form) {
    const StereoResult& r = form ? A().box : A().whole;
    SCOPED_TRACE(form ? "changed-box output" : "whole-image output");
    const fs::path out = test::output_dir(form ? "outputs_images_box" : "outputs_images_whole");
    const FrameNames n{"frame_0007", "frame_0008"};
    const Status s = write_frame_images(out, n, A().raw, r);
    ASSERT_TRUE(s) << s.error().message;
    const int w = 1280, h = 960;

    const cv::Mat aug_l = cv::imread((out / "left/augmented/frame_0007.png").string(), cv::IMREAD_UNCHANGED);
    const cv::Mat aug_r = cv::imread((out / "right/augmented/frame_0008.png").string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(aug_l.type(), CV_8UC3);
    EXPECT_TRUE(same(aug_l, expected_bgr(A().raw.left.image, r.left)));
    EXPECT_TRUE(same(aug_r, expected_bgr(A().raw.right.image, r.right)));
    // And it is augmented: the boom changed pixels of the raw frame.
    EXPECT_FALSE(same(aug_l, expected_bgr(A().raw.left.image, ViewResult{})));

    const cv::Mat mask_l = cv::imread((out / "left/mask/frame_0007.png").string(), cv::IMREAD_UNCHANGED);
    const cv::Mat mask_r = cv::imread((out / "right/mask/frame_0008.png").string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(mask_l.type(), CV_8UC1);
    EXPECT_TRUE(same(mask_l, mask_mat(r.left.mask)));
    EXPECT_TRUE(same(mask_r, mask_mat(r.right.mask)));
    // The masks hold every value 0..3.
    for (int v = 0; v < 4; ++v) EXPECT_GT(cv::countNonZero(mask_l == v), 0) << "mask value " << v;

    auto ml = [&](int x, int y) { return r.left.mask.row(y)[x] & 3; };
    auto mr = [&](int x, int y) { return r.right.mask.row(y)[x] & 3; };
    const cv::Mat overlap = paint(w, h, [&](int x, int y) {
      const bool l = ml(x, y) & 1, rr = mr(x, y) & 1;
      return l && rr ? kGreen : l ? kCyan : rr ? kBlue : kBlack;
    });
    EXPECT_TRUE(same(cv::imread((out / "vis/boom_overlap/frame_0007.png").string()), overlap));
    const cv::Mat occ_l = paint(w, h, [&](int x, int y) {
      const cv::Vec3b lut[4] = {kBlack, kCyan, kRed, kWhite};
      return lut[ml(x, y)];
    });
    EXPECT_TRUE(same(cv::imread((out / "vis/occlusion_left/frame_0007.png").string()), occ_l));
    const cv::Mat occ_r = paint(w, h, [&](int x, int y) {
      const cv::Vec3b lut[4] = {kBlack, kBlue, kRed, kMagenta};
      return lut[mr(x, y)];
    });
    EXPECT_TRUE(same(cv::imread((out / "vis/occlusion_right/frame_0008.png").string()), occ_r));
    const cv::Mat classes = paint(w, h, [&](int x, int y) {
      const cv::Vec3b lut[5] = {kBlack, kRed, kCyan, kBlue, kGreen};  // none, both, left, right, neither
      return lut[r.stereo_classes[static_cast<std::size_t>(y) * w + x]];
    });
    EXPECT_TRUE(same(cv::imread((out / "vis/stereo_classes/frame_0007.png").string()), classes));
    // Nothing else was written.
    int files = 0;
    for (const auto& e : fs::recursive_directory_iterator(out)) files += e.is_regular_file();
    EXPECT_EQ(files, 8);
  }
}

TEST_F(OutputsTest, WithoutStereoClassesNoClassPicture) {
  StereoResult r = A().whole;
  r.stereo_classes.clear();
  const fs::path out = test::output_dir("outputs_images_no_classes");
  ASSERT_TRUE(write_frame_images(out, {"a", "b"}, A().raw, r));
  EXPECT_TRUE(fs::exists(out / "vis/occlusion_left/a.png"));
  EXPECT_FALSE(fs::exists(out / "vis/stereo_classes"));
}

TEST_F(OutputsTest, AFolderThatCannotBeMadeFailsNamingIt) {
  const fs::path dir = test::output_dir("outputs_images_blocked");
  std::ofstream(dir / "left") << "a file where the folder should be";
  const Status s = write_frame_images(dir, {"a", "b"}, A().raw, A().whole);
  ASSERT_FALSE(s);
  EXPECT_TRUE(has(s.error().message, (dir / "left").string())) << s.error().message;
  const Status g = write_ground_truth(dir, {"a", "b"}, A().whole, A().rig);
  ASSERT_FALSE(g);
  EXPECT_TRUE(has(g.error().message, (dir / "left").string())) << g.error().message;
}

// An .npy file parsed here: the header dict as text, and the float32 data after it.
struct Npy {
  std::string header;
  std::vector<float> values;
};
Npy read_npy(const fs::path& p) {
  Npy n;
  std::ifstream in(p, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_GE(bytes.size(), 10u);
  if (bytes.size() < 10) return n;
  EXPECT_EQ(bytes.substr(0, 6), std::string("\x93NUMPY", 6)) << p;
  EXPECT_EQ(bytes[6], 1) << "version 1.0";
  EXPECT_EQ(bytes[7], 0);
  const std::size_t hlen = static_cast<unsigned char>(bytes[8]) |
                           static_cast<std::size_t>(static_cast<unsigned char>(bytes[9])) << 8;
  EXPECT_EQ((10 + hlen) % 16, 0u) << "the data aligned";
  n.header = bytes.substr(10, hlen);
  EXPECT_EQ(n.header.back(), '\n');
  const std::size_t data = 10 + hlen;
  n.values.resize((bytes.size() - data) / 4);
  EXPECT_EQ((bytes.size() - data) % 4, 0u);
  for (std::size_t i = 0; i < n.values.size(); ++i) {
    const auto* b = reinterpret_cast<const unsigned char*>(bytes.data() + data + 4 * i);
    const std::uint32_t u =
        b[0] | b[1] << 8 | b[2] << 16 | static_cast<std::uint32_t>(b[3]) << 24;  // little-endian
    std::memcpy(&n.values[i], &u, 4);
  }
  return n;
}

std::string no_spaces(std::string s) {
  std::erase(s, ' ');
  return s;
}

TEST_F(OutputsTest, GroundTruthFilesHoldTheDepthTheCorrespondenceAndTheClasses) {
  const StereoResult& r = A().whole;
  const Rig& rig = A().rig;
  const fs::path out = test::output_dir("outputs_ground_truth");
  const Status s = write_ground_truth(out, {"frame_0001", "frame_0002"}, r, rig);
  ASSERT_TRUE(s) << s.error().message;
  const int w = 1280, h = 960;

  const ViewResult* views[2] = {&r.left, &r.right};
  const char* stems[2] = {"left/depth/frame_0001.npy", "right/depth/frame_0002.npy"};
  const char* pngs[2] = {"left/depth_mm/frame_0001.png", "right/depth_mm/frame_0002.png"};
  for (int c = 0; c < 2; ++c) {
    SCOPED_TRACE(c ? "right" : "left");
    const DepthImage& d = views[c]->receiver_depth;
    ASSERT_EQ(d.width, w);
    ASSERT_EQ(d.height, h);
    const Npy npy = read_npy(out / stems[c]);
    const std::string hd = no_spaces(npy.header);
    EXPECT_TRUE(has(hd, "'descr':'<f4'")) << npy.header;
    EXPECT_TRUE(has(hd, "'fortran_order':False")) << npy.header;
    EXPECT_TRUE(has(hd, "'shape':(960,1280)")) << npy.header;
    ASSERT_EQ(npy.values.size(), static_cast<std::size_t>(w) * h);
    const cv::Mat mm = cv::imread((out / pngs[c]).string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(mm.type(), CV_16UC1);
    ASSERT_EQ(mm.cols, w);
    long receiver = 0, mismatch_npy = 0, mismatch_mm = 0, not_nan = 0, mask_disagrees = 0;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const float z = d.at(x, y);
        const float v = npy.values[static_cast<std::size_t>(y) * w + x];
        const std::uint16_t m = mm.at<std::uint16_t>(y, x);
        const bool on = (views[c]->mask.row(y)[x] & kMaskReceiver) != 0;
        if (std::isfinite(z)) {
          ++receiver;
          mismatch_npy += v != z;
          const double want = std::min(65535.0, std::round(static_cast<double>(z) * 1000.0));
          mismatch_mm += m != static_cast<std::uint16_t>(want);
        } else {
          not_nan += !std::isnan(v);
          mismatch_mm += m != 0;
        }
        mask_disagrees += on != std::isfinite(z);
      }
    EXPECT_GT(receiver, 1000);
    EXPECT_EQ(mismatch_npy, 0) << "the depth, float32, as the result has it";
    EXPECT_EQ(not_nan, 0) << "NaN where there is no receiver";
    EXPECT_EQ(mismatch_mm, 0) << "round(z * 1000), 0 where none";
    EXPECT_EQ(mask_disagrees, 0) << "depth exactly where the mask says receiver";
  }

  // The correspondence: each left receiver pixel's point through the right camera, done here for
  // the paper's pinhole cameras (pixel centres at integer coordinates).
  const Npy uv = read_npy(out / "left/right_px/frame_0001.npy");
  EXPECT_TRUE(has(no_spaces(uv.header), "'shape':(960,1280,2)")) << uv.header;
  EXPECT_TRUE(has(no_spaces(uv.header), "'descr':'<f4'")) << uv.header;
  ASSERT_EQ(uv.values.size(), static_cast<std::size_t>(w) * h * 2);
  const CameraModel& L = rig.left().model;
  const CameraModel& R = rig.right().model;
  ASSERT_EQ(L.distortion, DistortionModel::kNone);
  const Pose T_rl = rig.right().T_body_cam.inverse() * rig.left().T_body_cam;
  double worst = 0;
  long checked = 0, stray = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float z = r.left.receiver_depth.at(x, y);
      const std::size_t i = 2 * (static_cast<std::size_t>(y) * w + x);
      if (!std::isfinite(z)) {
        stray += !std::isnan(uv.values[i]) || !std::isnan(uv.values[i + 1]);
        continue;
      }
      const Eigen::Vector3d p_left((x - L.cx_px) / L.fx_px * z, (y - L.cy_px) / L.fy_px * z, z);
      const Eigen::Vector3d p = T_rl * p_left;
      const double u = R.fx_px * p.x() / p.z() + R.cx_px, v = R.fy_px * p.y() / p.z() + R.cy_px;
      worst = std::max({worst, std::abs(uv.values[i] - u), std::abs(uv.values[i + 1] - v)});
      ++checked;
    }
  EXPECT_GT(checked, 1000);
  EXPECT_LT(worst, 2e-3) << "px";
  EXPECT_EQ(stray, 0) << "NaN where the left pixel has no receiver";

  const cv::Mat cls = cv::imread((out / "left/stereo_class/frame_0001.png").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(cls.type(), CV_8UC1);
  ASSERT_EQ(cls.total(), r.stereo_classes.size());
  EXPECT_EQ(std::memcmp(cls.data, r.stereo_classes.data(), r.stereo_classes.size()), 0);
  // The right camera has no class or correspondence file of its own.
  EXPECT_FALSE(fs::exists(out / "right/right_px"));
  EXPECT_FALSE(fs::exists(out / "right/stereo_class"));
}

TEST_F(OutputsTest, GroundTruthNeedsTheDepthImages) {
  StereoResult r = A().whole;
  r.right.receiver_depth = DepthImage{};
  const fs::path out = test::output_dir("outputs_ground_truth_no_depth");
  const Status s = write_ground_truth(out, {"a", "b"}, r, A().rig);
  ASSERT_FALSE(s);
  EXPECT_TRUE(has(s.error().message, "right")) << s.error().message;
  // Without classes: everything but the class picture.
  StereoResult nc = A().whole;
  nc.stereo_classes.clear();
  ASSERT_TRUE(write_ground_truth(out, {"a", "b"}, nc, A().rig));
  EXPECT_TRUE(fs::exists(out / "left/right_px/a.npy"));
  EXPECT_FALSE(fs::exists(out / "left/stereo_class/a.png"));
}

TEST_F(OutputsTest, FrameRecordHoldsTheImagesAsMade) {
  // Whole images: recorded whole, no box.
  const StereoResult& w = A().whole;
  const recorder::FrameRecord fw = frame_record(w);
  for (int c = 0; c < 2; ++c) {
    const ViewResult& v = c ? w.right : w.left;
    EXPECT_FALSE(fw.augmented_box[c]) << c;
    EXPECT_TRUE(pixels_equal(fw.augmented[c], v.augmented)) << c;
    EXPECT_EQ(fw.augmented[c].width(), 1280);
    EXPECT_TRUE(pixels_equal(fw.mask[c], v.mask)) << c;
    EXPECT_TRUE(fw.receiver_depth[c].empty()) << "no ground truth asked for";
  }
  ASSERT_TRUE(fw.stats);
  EXPECT_EQ(fw.stats->receiver_px_left, w.stats.receiver_px_left);
  EXPECT_EQ(fw.stats->occluded_px_right, w.stats.occluded_px_right);
  EXPECT_EQ(fw.stats->stereo_both_px, w.stats.stereo_both_px);
  EXPECT_TRUE(fw.raw.left.image.empty()) << "the caller adds the raw frame";
  EXPECT_FALSE(fw.boom);
  EXPECT_FALSE(fw.T_body_receiver);

  // Changed boxes: the box images with their boxes; over the raw frame they give the whole image.
  const StereoResult& b = A().box;
  const recorder::FrameRecord fb = frame_record(b, true);
  for (int c = 0; c < 2; ++c) {
    const ViewResult& v = c ? b.right : b.left;
    ASSERT_TRUE(fb.augmented_box[c]) << c;
    EXPECT_EQ(*fb.augmented_box[c], v.augmented_box);
    EXPECT_EQ(fb.augmented[c].width(), v.augmented_box.width());
    EXPECT_TRUE(pixels_equal(fb.augmented[c], v.augmented));
    const Image& raw = c ? A().raw.right.image : A().raw.left.image;
    ViewResult as_recorded;
    as_recorded.augmented = fb.augmented[c];
    as_recorded.augmented_box = *fb.augmented_box[c];
    EXPECT_TRUE(same(expected_bgr(raw, as_recorded), expected_bgr(raw, c ? w.right : w.left)))
        << "the box over the raw frame is the whole augmented image";
    // With the ground truth: the depth, its box only, giving the whole depth image back.
    const recorder::DepthRecord& d = fb.receiver_depth[c];
    ASSERT_FALSE(d.empty()) << c;
    EXPECT_EQ(d.width, 1280);
    EXPECT_EQ(d.height, 960);
    EXPECT_LT(d.box.width(), 1280);
    const DepthImage back = d.image();
    ASSERT_EQ(back.z_m.size(), v.receiver_depth.z_m.size());
    long differ = 0;
    for (std::size_t i = 0; i < back.z_m.size(); ++i) {
      const float a = back.z_m[i], e = v.receiver_depth.z_m[i];
      differ += !(a == e || (std::isinf(a) && std::isinf(e)));
    }
    EXPECT_EQ(differ, 0) << c;
  }
}

}  // namespace
}  // namespace augrig::pipeline
