// The augrig command, run as a real binary: help and exit codes, one-line errors naming the bad
// input, and `augment` / `demo` outputs checked against the masks they wrote.
#include "app/commands.hpp"

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "core/npy.hpp"
#include "nav/logs.hpp"
#include "recorder/reader.hpp"
#include "render/camera_look.hpp"
#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

namespace fs = std::filesystem;
using test::augrig_binary;
using test::data_path;
using test::output_dir;
using test::run_command;

const char* kCsvHeader =
    "t_ns,receiver_px_left,receiver_px_right,boom_px_left,boom_px_right,boom_overlap_px,boom_overlap_pct_"
    "union,"
    "occluded_px_left,occluded_px_right,occluded_pct_left,occluded_pct_right,stereo_both_px,left_only_px,"
    "right_only_px,neither_px,receiver_pct_left,receiver_pct_right,boom_pct_left,boom_pct_right,"
    "shadow_px_left,shadow_px_right,shadow_pct_left,shadow_pct_right";

int augrig(const std::string& args, std::string* output = nullptr) {
  return run_command(augrig_binary() + " " + args, output);
}

// A deterministic textured image (smooth ramps plus a checker), so "unchanged" is a real test.
cv::Mat pattern(int w, int h, int type, int seed) {
  cv::Mat m(h, w, type);
  const int ch = m.channels();
  for (int y = 0; y < h; ++y) {
    auto* row = m.ptr<std::uint8_t>(y);
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < ch; ++c)
        row[x * ch + c] = static_cast<std::uint8_t>(
            (x * (3 + c) + y * (5 - c) + seed * 40 + ((x / 16 + y / 16) & 1) * 60) & 255);
  }
  return m;
}

std::vector<std::string> read_lines(const fs::path& p) {
  std::ifstream in(p);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  return lines;
}

std::vector<long long> csv_row(const std::string& line) {
  std::vector<long long> v;
  std::stringstream ss(line);
  for (std::string cell; std::getline(ss, cell, ',');) v.push_back(static_cast<long long>(std::stod(cell)));
  return v;
}

// ---- In-process: the argument parser ------------------------------------------------------------

TEST(ParseArgs, AcceptsBothValueSpellingsAndFlags) {
  const std::vector<app::OptionSpec> specs = {{"out", app::ArgKind::kValue, "DIR", "", true},
                                              {"fast", app::ArgKind::kFlag, "", ""},
                                              {"bayer", app::ArgKind::kOptionalValue, "", ""}};
  const auto p = app::parse_args({"--out", "a b", "--fast", "--bayer=GR"}, specs);
  ASSERT_TRUE(p) << p.error().message;
  EXPECT_EQ(p->get("out"), "a b");
  EXPECT_TRUE(p->has("fast"));
  EXPECT_EQ(p->get("bayer"), "GR");
  const auto q = app::parse_args({"--out=x", "--bayer"}, specs);
  ASSERT_TRUE(q);
  EXPECT_EQ(q->get("out"), "x");
  EXPECT_TRUE(q->has("bayer"));
  EXPECT_FALSE(app::parse_args({"--out"}, specs));                     // missing value
  EXPECT_FALSE(app::parse_args({"--fast"}, specs));                    // missing required
  EXPECT_FALSE(app::parse_args({"--out", "x", "--out", "y"}, specs));  // twice
  EXPECT_FALSE(app::parse_args({"--out", "x", "--fast=1"}, specs));    // flag with a value
  EXPECT_FALSE(app::parse_args({"--out", "x", "stray"}, specs));
  EXPECT_TRUE(app::parse_args({"--help"}, specs));  // help needs no required options
}

// ---- The binary: help, exit codes, errors ---------------------------------------------------------

TEST(ImageFiles, WriteLeavesTheCallersPixelsAloneAndReadsBackEqual) {
  const std::string dir = test::output_dir("image_files");
  for (PixelFormat f : {PixelFormat::kRGB8, PixelFormat::kRGBA8, PixelFormat::kMono8}) {
    Image img(7, 5, f);
    for (std::size_t i = 0; i < img.size_bytes(); ++i) img.data()[i] = static_cast<std::uint8_t>(37 * i + 11);
    const Image before = Image::copy_of(img.cview());
    const std::string path = dir + "/" + std::string(to_string(f)) + ".png";
    ASSERT_TRUE(app::write_image_file(path, img));
    EXPECT_TRUE(pixels_equal(img, before)) << "write_image_file changed its input";
    auto back = app::read_image_file(path);
    ASSERT_TRUE(back) << back.error().message;
    EXPECT_TRUE(pixels_equal(*back, before)) << to_string(f);
  }
}

TEST(Cli, HelpAndVersionExitZero) {
  for (const char* args : {"--help", "-h", "augment --help", "demo --help", "augment -h", "--version"}) {
    std::string out;
    EXPECT_EQ(augrig(args, &out), 0) << args << ":\n" << out;
    EXPECT_FALSE(out.empty()) << args;
  }
  std::string out;
  augrig("--version", &out);
  EXPECT_NE(out.find("augrig 0."), std::string::npos) << out;
  augrig("augment --help", &out);
  for (const char* flag : {"--rig", "--scene", "--left", "--right", "--out", "--format", "--bayer",
                           "--no-receiver", "--receiver-draw"})
    EXPECT_NE(out.find(flag), std::string::npos) << flag;
}

TEST(Cli, UsageErrorsExitTwo) {
  std::string out;
  EXPECT_EQ(augrig("", &out), 2);
  EXPECT_EQ(augrig("frobnicate", &out), 2);
  EXPECT_NE(out.find("unknown command 'frobnicate'"), std::string::npos) << out;
  EXPECT_EQ(augrig("augment --rig default --bogus 1", &out), 2);
  EXPECT_NE(out.find("--bogus"), std::string::npos) << out;
  EXPECT_EQ(augrig("augment --rig default --scene s.yaml --left l.png --right r.png", &out), 2);
  EXPECT_NE(out.find("--out"), std::string::npos) << out;  // names the missing flag
  EXPECT_EQ(augrig("demo --out /tmp/x --frames zero", &out), 2);
  EXPECT_EQ(augrig("demo --out /tmp/x --receiver-draw solid", &out), 2);
}

// Test inputs shared by the error tests: a valid pair at the rig's resolution.
class AugmentInputs : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = output_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    left_ = dir_ + "/left.png";
    right_ = dir_ + "/right.png";
    ASSERT_TRUE(cv::imwrite(left_, pattern(1280, 960, CV_8UC3, 0)));
    ASSERT_TRUE(cv::imwrite(right_, pattern(1280, 960, CV_8UC3, 1)));
  }
  std::string args(const std::string& left, const std::string& right, const std::string& rig = "default",
                   const std::string& scene = data_path("scenes/contact.yaml")) const {
    return "augment --rig " + rig + " --scene " + scene + " --left " + left + " --right " + right +
           " --out " + dir_ + "/out";
  }
  std::string dir_, left_, right_;
};

TEST_F(AugmentInputs, MissingImageExitsOneNamingIt) {
  std::string out;
  EXPECT_EQ(augrig(args(left_, dir_ + "/nope.png"), &out), 1) << out;
  EXPECT_NE(out.find("augrig augment: " + dir_ + "/nope.png"), std::string::npos) << out;
}

TEST_F(AugmentInputs, CorruptPngExitsOneNamingIt) {
  const std::string bad = dir_ + "/x.png";
  std::ofstream f(bad, std::ios::binary);
  std::mt19937 rng(7);
  for (int i = 0; i < 4096; ++i) f.put(static_cast<char>(rng() & 255));
  f.close();
  std::string out;
  EXPECT_EQ(augrig(args(bad, right_), &out), 1) << out;
  EXPECT_NE(out.find(bad), std::string::npos) << out;
}

TEST_F(AugmentInputs, WrongSizeExitsOneNamingBothSizes) {
  const std::string small = dir_ + "/small.png";
  ASSERT_TRUE(cv::imwrite(small, pattern(640, 480, CV_8UC3, 0)));
  std::string out;
  EXPECT_EQ(augrig(args(left_, small), &out), 1) << out;
  EXPECT_NE(out.find(small), std::string::npos) << out;
  EXPECT_NE(out.find("640x480"), std::string::npos) << out;
  EXPECT_NE(out.find("1280x960"), std::string::npos) << out;
}

TEST_F(AugmentInputs, SixteenBitImageExitsOne) {
  const std::string deep = dir_ + "/deep.png";
  cv::Mat m(960, 1280, CV_16UC1, cv::Scalar(1000));
  ASSERT_TRUE(cv::imwrite(deep, m));
  std::string out;
  EXPECT_EQ(augrig(args(deep, right_), &out), 1) << out;
  EXPECT_NE(out.find(deep + ": has 16-bit samples"), std::string::npos) << out;
}

TEST_F(AugmentInputs, BadRigExitsOneNamingFileAndLine) {
  const std::string rig = dir_ + "/bad_rig.yaml";
  std::ofstream(rig) << "augrig_rig: 1\ncameras: oops\n";
  std::string out;
  EXPECT_EQ(augrig(args(left_, right_, rig), &out), 1) << out;
  EXPECT_NE(out.find(rig + ":2:"), std::string::npos) << out;
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << "one line:\n" << out;
}

TEST_F(AugmentInputs, BadSceneExitsOneNamingFileLineAndKey) {
  std::string out;
  const std::string scene = data_path("scenes/bad_boom_limits.yaml");
  EXPECT_EQ(augrig(args(left_, right_, "default", scene), &out), 1) << out;
  EXPECT_NE(out.find("augrig augment: " + scene + ":5:"), std::string::npos) << out;
  EXPECT_NE(out.find("boom.extension_m"), std::string::npos) << out;
}

TEST_F(AugmentInputs, FolderCountMismatchNamesBothFolders) {
  fs::create_directories(dir_ + "/L");
  fs::create_directories(dir_ + "/R");
  fs::copy_file(left_, dir_ + "/L/a.png");
  fs::copy_file(left_, dir_ + "/L/b.png");
  fs::copy_file(right_, dir_ + "/R/a.png");
  std::string out;
  EXPECT_EQ(augrig(args(dir_ + "/L", dir_ + "/R"), &out), 1) << out;
  EXPECT_NE(out.find(dir_ + "/L has 2"), std::string::npos) << out;
  EXPECT_NE(out.find(dir_ + "/R has 1"), std::string::npos) << out;
  EXPECT_EQ(augrig(args(dir_ + "/L", right_), &out), 2) << out;  // folder with a file
}

// ---- augment: the outputs ------------------------------------------------------------------------

struct MaskCounts {
  long long receiver_l = 0, receiver_r = 0, boom_l = 0, boom_r = 0, overlap = 0, occluded_l = 0,
            occluded_r = 0, shadow_l = 0, shadow_r = 0;
};

// Checks one camera's outputs; returns its mask.
cv::Mat check_view(const fs::path& out, const std::string& side, const cv::Mat& input) {
  const cv::Mat aug = cv::imread((out / side / "augmented" / "in.png").string(), cv::IMREAD_UNCHANGED);
  const cv::Mat mask = cv::imread((out / side / "mask" / "in.png").string(), cv::IMREAD_UNCHANGED);
  EXPECT_EQ(aug.size(), input.size()) << side;
  EXPECT_EQ(aug.type(), input.type()) << side;
  EXPECT_EQ(mask.size(), input.size()) << side;
  EXPECT_EQ(mask.type(), CV_8UC1) << side;
  if (aug.size() != input.size() || aug.type() != input.type() || mask.type() != CV_8UC1) return {};
  long long changed_outside = 0;
  const int reach = psf_margin_px(CameraLookParams{});
  for (int y = 0; y < mask.rows; ++y) {
    for (int x = 0; x < mask.cols; ++x) {
      EXPECT_LE(mask.at<std::uint8_t>(y, x), 7) << side << " mask at " << x << "," << y;
      // Far from the boom and its shadow (no boom or shadow bit within the default camera look's
      // PSF reach) the raw pixel must come through untouched.
      bool near_boom = false;
      for (int dy = -reach; dy <= reach; ++dy)
        for (int dx = -reach; dx <= reach; ++dx) {
          const int u = x + dx, v = y + dy;
          if (u >= 0 && v >= 0 && u < mask.cols && v < mask.rows && (mask.at<std::uint8_t>(v, u) & 5))
            near_boom = true;
        }
      if (!near_boom && aug.at<cv::Vec3b>(y, x) != input.at<cv::Vec3b>(y, x)) ++changed_outside;
    }
  }
  EXPECT_EQ(changed_outside, 0) << side << ": pixels changed away from the boom";
  return mask;
}

TEST(Augment, SinglePairAtContactWritesConsistentOutputs) {
  const std::string dir = output_dir("augment_single_pair");
  const cv::Mat left = pattern(1280, 960, CV_8UC3, 0), right = pattern(1280, 960, CV_8UC3, 1);
  fs::create_directories(dir + "/in_l");
  fs::create_directories(dir + "/in_r");
  ASSERT_TRUE(cv::imwrite(dir + "/in_l/in.png", left));
  ASSERT_TRUE(cv::imwrite(dir + "/in_r/in.png", right));
  const fs::path out = dir + "/out";
  std::string log;
  ASSERT_EQ(augrig("augment --rig default --scene " + data_path("scenes/contact.yaml") + " --left " + dir +
                       "/in_l/in.png --right " + dir + "/in_r/in.png --out " + out.string(),
                   &log),
            0)
      << log;
  EXPECT_NE(log.find("Boom occlusion left"), std::string::npos) << log;  // format_table1 on stdout

  const cv::Mat ml = check_view(out, "left", left), mr = check_view(out, "right", right);
  ASSERT_FALSE(ml.empty());
  ASSERT_FALSE(mr.empty());
  for (const char* vis : {"boom_overlap", "occlusion_left", "occlusion_right", "stereo_classes"}) {
    const cv::Mat v = cv::imread((out / "vis" / vis / "in.png").string(), cv::IMREAD_UNCHANGED);
    EXPECT_EQ(v.size(), cv::Size(1280, 960)) << vis;
    EXPECT_EQ(v.type(), CV_8UC3) << vis;
  }

  // Brute-force counts over the written masks must equal the CSV.
  MaskCounts c;
  for (int y = 0; y < ml.rows; ++y)
    for (int x = 0; x < ml.cols; ++x) {
      const int l = ml.at<std::uint8_t>(y, x), r = mr.at<std::uint8_t>(y, x);
      c.receiver_l += (l & 2) != 0, c.receiver_r += (r & 2) != 0;
      c.boom_l += l & 1, c.boom_r += r & 1, c.overlap += (l & r & 1);
      c.occluded_l += (l & 3) == 3, c.occluded_r += (r & 3) == 3;
      c.shadow_l += (l & 4) != 0, c.shadow_r += (r & 4) != 0;
    }
  const auto lines = read_lines(out / "stats.csv");
  ASSERT_EQ(lines.size(), 2u);
  EXPECT_EQ(lines[0], kCsvHeader);
  const auto v = csv_row(lines[1]);
  ASSERT_EQ(v.size(), 23u);
  EXPECT_EQ(v[0], 1000000000);  // t_ns from the scene file
  EXPECT_EQ(v[1], c.receiver_l);
  EXPECT_EQ(v[2], c.receiver_r);
  EXPECT_EQ(v[3], c.boom_l);
  EXPECT_EQ(v[4], c.boom_r);
  EXPECT_EQ(v[5], c.overlap);
  EXPECT_EQ(v[7], c.occluded_l);
  EXPECT_EQ(v[8], c.occluded_r);
  EXPECT_EQ(v[11] + v[12] + v[13] + v[14], c.receiver_l);  // stereo classes partition the left receiver
  EXPECT_EQ(v[19], c.shadow_l);
  EXPECT_EQ(v[20], c.shadow_r);
  // At contact the boom and receiver are both in view and the boom hides part of the receiver.
  EXPECT_GT(c.boom_l, 1000);
  EXPECT_GT(c.receiver_l, 1000);
  EXPECT_GT(c.occluded_l, 0);
}

// --ground-truth: the depth files agree with the masks and with each other, the correspondence
// lands on the receiver in the right view wherever the classes say the right camera sees the
// point, and the class image partitions the left receiver as stats.csv counts it.
TEST(Augment, GroundTruthFilesAgreeWithTheMasksAndAcrossTheViews) {
  const std::string dir = output_dir("augment_ground_truth");
  const cv::Mat left = pattern(1280, 960, CV_8UC3, 0), right = pattern(1280, 960, CV_8UC3, 1);
  ASSERT_TRUE(cv::imwrite(dir + "/l.png", left));
  ASSERT_TRUE(cv::imwrite(dir + "/r.png", right));
  const fs::path out = dir + "/out";
  std::string log;
  ASSERT_EQ(augrig("augment --rig default --scene " + data_path("scenes/contact.yaml") + " --left " + dir +
                       "/l.png --right " + dir + "/r.png --out " + out.string() + " --ground-truth",
                   &log),
            0)
      << log;
  const auto csv = csv_row(read_lines(out / "stats.csv").at(1));
  std::array<NpyArray, 2> depth;
  std::array<cv::Mat, 2> mask, mm;
  for (int c = 0; c < 2; ++c) {
    const fs::path side = out / (c ? "right" : "left");
    auto d = read_npy_f32((side / "depth" / (c ? "r.npy" : "l.npy")).string());
    ASSERT_TRUE(d) << d.error().message;
    depth[c] = *d;
    ASSERT_EQ(depth[c].shape, (std::vector<std::int64_t>{960, 1280}));
    mask[c] = cv::imread((side / "mask" / (c ? "r.png" : "l.png")).string(), cv::IMREAD_UNCHANGED);
    mm[c] = cv::imread((side / "depth_mm" / (c ? "r.png" : "l.png")).string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(mm[c].type(), CV_16UC1);
    ASSERT_EQ(mask[c].size(), cv::Size(1280, 960));
    std::int64_t receiver = 0, mismatched = 0, bad_mm = 0;
    for (int y = 0; y < 960; ++y)
      for (int x = 0; x < 1280; ++x) {
        const float z = depth[c].values[static_cast<std::size_t>(y) * 1280 + x];
        const bool has = (mask[c].at<std::uint8_t>(y, x) & 2) != 0;
        receiver += has;
        mismatched += has != std::isfinite(z);
        const int expect_mm = std::isfinite(z) ? static_cast<int>(std::lround(z * 1000.0)) : 0;
        bad_mm += mm[c].at<std::uint16_t>(y, x) != expect_mm;
      }
    EXPECT_EQ(receiver, csv[1 + c]) << "receiver pixels, camera " << c;
    EXPECT_EQ(mismatched, 0) << "depth finite exactly where the mask has the receiver, camera " << c;
    EXPECT_EQ(bad_mm, 0) << "16-bit mm = the float depth rounded, camera " << c;
  }
  auto uv = read_npy_f32((out / "left" / "right_px" / "l.npy").string());
  ASSERT_TRUE(uv) << uv.error().message;
  ASSERT_EQ(uv->shape, (std::vector<std::int64_t>{960, 1280, 2}));
  const cv::Mat cls = cv::imread((out / "left" / "stereo_class" / "l.png").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(cls.type(), CV_8UC1);
  std::array<std::int64_t, 5> counts{};
  std::int64_t both_checked = 0, both_off_receiver = 0, uv_mismatch = 0;
  for (int y = 0; y < 960; ++y)
    for (int x = 0; x < 1280; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * 1280 + x;
      const int k = cls.at<std::uint8_t>(y, x);
      ASSERT_LE(k, 4);
      ++counts[k];
      const bool has = std::isfinite(depth[0].values[i]);
      EXPECT_EQ(k != 0, has) << x << "," << y;
      const float u = uv->values[2 * i], v = uv->values[2 * i + 1];
      uv_mismatch += std::isfinite(u) != has;
      // Seen by both: the right view has the receiver where the point projects.
      if (k == 1 && std::isfinite(u)) {
        ++both_checked;
        const int ur = static_cast<int>(std::lround(u)), vr = static_cast<int>(std::lround(v));
        both_off_receiver +=
            ur < 0 || vr < 0 || ur >= 1280 || vr >= 960 || !(mask[1].at<std::uint8_t>(vr, ur) & 2);
      }
    }
  EXPECT_EQ(uv_mismatch, 0) << "a correspondence exactly where the left view has the receiver";
  EXPECT_EQ(counts[1], csv[11]);
  EXPECT_EQ(counts[2], csv[12]);
  EXPECT_EQ(counts[3], csv[13]);
  EXPECT_EQ(counts[4], csv[14]);
  EXPECT_GT(both_checked, 1000);
  // Rounding to the nearest pixel at the receiver's silhouette may step off it: a thin margin.
  EXPECT_LT(static_cast<double>(both_off_receiver), 0.01 * static_cast<double>(both_checked));

  // Without --out nothing could be written: a usage error (exit 2) in replay and run.
  EXPECT_EQ(augrig("replay " + dir + " --ground-truth"), 2);
  EXPECT_EQ(augrig("run --source sim://demo --ground-truth --frames 1 --headless"), 2);
}

TEST(Augment, FoldersOfBayerPairs) {
  const std::string dir = output_dir("augment_bayer_folders");
  for (const char* side : {"L", "R"}) {
    fs::create_directories(dir + "/" + side);
    for (int i = 0; i < 2; ++i)
      ASSERT_TRUE(
          cv::imwrite(dir + "/" + side + "/f" + std::to_string(i) + ".png", pattern(1280, 960, CV_8UC1, i)));
  }
  std::string log;
  ASSERT_EQ(augrig("augment --rig default --scene " + data_path("scenes/body.yaml") + " --left " + dir +
                       "/L --right " + dir + "/R --out " + dir + "/out --bayer RG --sink yolo:" + dir + "/yolo",
                   &log),
            0)
      << log;
  EXPECT_NE(log.find("Run summary over 2"), std::string::npos) << log;
  // --sink: the labels' images debayered to colour, one label file per image.
  EXPECT_NE(log.find(dir + "/yolo: 4 image(s) of 2 pair(s) labelled in YOLO's pose format"), std::string::npos)
      << log;
  const cv::Mat labelled = cv::imread(dir + "/yolo/images/000001_right.png", cv::IMREAD_UNCHANGED);
  EXPECT_EQ(labelled.type(), CV_8UC3);
  EXPECT_TRUE(fs::exists(dir + "/yolo/labels/000001_right.txt"));
  for (const char* f : {"f0", "f1"}) {
    const cv::Mat aug = cv::imread(dir + "/out/left/augmented/" + f + ".png", cv::IMREAD_UNCHANGED);
    EXPECT_EQ(aug.type(), CV_8UC1) << f;  // Bayer stays a raw mosaic, written as 8-bit gray
    EXPECT_EQ(aug.size(), cv::Size(1280, 960)) << f;
  }
  const auto lines = read_lines(fs::path(dir) / "out" / "stats.csv");
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(csv_row(lines[1])[0], 0);  // no t_ns in the scene: the frame index
  EXPECT_EQ(csv_row(lines[2])[0], 1);
}

// ---- augment: a flown sequence (sim -> nav -> augment --frames --poses) ---------------------------

// `augrig sim` of a short approach (every 3rd frame: 21 pairs), once per test process. CTest runs
// each test in a process of its own and in parallel, so each has its own folder (a shared one was
// removed and rewritten by one test while another read it).
const std::string& flown_dataset() {
  static const std::string dir = [] {
    const std::string d = output_dir(std::string("augment_flown_") +
                                     testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(d);
    std::string log;
    EXPECT_EQ(augrig("sim --scenario " + data_path("scenarios/short_approach.yaml") + " --every 3 --out " +
                         d + "/D",
                     &log),
              0)
        << log;
    fs::create_directories(d + "/P");
    EXPECT_EQ(augrig("nav --tanker " + d + "/D/tanker --receiver " + d + "/D/receiver --rig " + d +
                         "/D/rig.yaml --frames " + d + "/D/frames/index.csv --out " + d + "/P/poses.csv",
                     &log),
              0)
        << log;
    return d;
  }();
  return dir;
}

std::map<long long, std::vector<long long>> stats_by_t(const fs::path& csv) {
  std::map<long long, std::vector<long long>> rows;
  const auto lines = read_lines(csv);
  for (std::size_t i = 1; i < lines.size(); ++i) {
    const auto v = csv_row(lines[i]);
    rows[v[0]] = v;
  }
  return rows;
}

TEST(Augment, FlownSequenceWithNavPosesAgreesWithTheTruthWithinTheNavError) {
  const std::string d = flown_dataset();
  const std::string common =
      "augment --rig " + d + "/D/rig.yaml --frames " + d + "/D/frames/index.csv --out ";
  std::string log, truth_log;
  ASSERT_EQ(augrig(common + d + "/O --poses " + d + "/P/poses.csv", &log), 0) << log;
  ASSERT_EQ(augrig(common + d + "/T --poses " + d + "/D/truth/poses.csv", &truth_log), 0) << truth_log;
  // Every frame read is in a pair: the ledger adds up, nothing unpaired or without a pose.
  EXPECT_NE(log.find("21 stereo pair(s) by timestamp"), std::string::npos) << log;
  EXPECT_NE(log.find("frames read: left 21, right 21 = 2 x 21 pairs + 0 unpaired"), std::string::npos) << log;
  EXPECT_EQ(log.find("without a pose"), std::string::npos) << log;
  // The per-frame images are named after the input files (the index's left/NNNNNN.png).
  for (const char* f : {"left/mask/000000.png", "right/mask/000060.png", "left/augmented/000030.png",
                        "vis/boom_overlap/000000.png"})
    EXPECT_TRUE(fs::exists(fs::path(d) / "O" / f)) << f;
  EXPECT_FALSE(fs::exists(fs::path(d) / "O" / ".augrig-staging"));

  // Against the truth: the receiver's pixel count depends on its range (area ~ 1/z^2: relative
  // change 2 dz/z) and on its attitude (a rotation by theta changes the projected area by at most
  // about theta times the whole: the receiver's side and top areas are no larger than its
  // silhouette's 2x). So per pair |n_nav - n_truth| <= (2 dz/z + 2 theta + 1 %) n_truth, with dz
  // and theta this pair's actual nav error (the 1 %: edge pixels that the silhouette's sub-pixel
  // shift flips). The boom is not compared: nav's boom tracks the estimated receptacle, the
  // truth's is the scenario's.
  auto nav = nav::read_camera_pose_csv(d + "/P/poses.csv");
  auto truth = nav::read_camera_pose_csv(d + "/D/truth/poses.csv");
  ASSERT_TRUE(nav && truth);
  std::map<std::pair<long long, int>, nav::CameraPoseRow> truth_at;
  for (const auto& r : truth->rows) truth_at[{r.t_ns, r.camera}] = r;
  const auto got = stats_by_t(fs::path(d) / "O" / "stats.csv"),
             want = stats_by_t(fs::path(d) / "T" / "stats.csv");
  ASSERT_EQ(got.size(), 21u);
  ASSERT_EQ(want.size(), 21u);
  int compared = 0;
  for (const auto& r : nav->rows) {
    const auto t = truth_at.find({r.t_ns, r.camera});
    ASSERT_NE(t, truth_at.end());
    const auto g = got.find(r.t_ns), w = want.find(r.t_ns);
    ASSERT_NE(g, got.end());
    ASSERT_NE(w, want.end());
    const double dz = std::abs(r.z_m - t->second.z_m) / t->second.z_m;
    const double dot =
        std::abs(r.qw * t->second.qw + r.qx * t->second.qx + r.qy * t->second.qy + r.qz * t->second.qz);
    const double theta = 2 * std::acos(std::min(1.0, dot));
    const double tol = 2 * dz + 2 * theta + 0.01;
    const int col = 1 + r.camera;  // receiver_px_left, receiver_px_right
    const double n_truth = static_cast<double>(w->second[col]);
    EXPECT_GT(n_truth, 1000) << "the receiver is in view at t_ns " << r.t_ns;
    EXPECT_LE(std::abs(static_cast<double>(g->second[col]) - n_truth), tol * n_truth)
        << "t_ns " << r.t_ns << " camera " << r.camera << ": nav " << g->second[col] << ", truth " << n_truth
        << ", tolerance " << tol * 100 << " %";
    ++compared;
  }
  EXPECT_EQ(compared, 42);
}

TEST(Augment, FlownSequenceCountsUnpairedFramesAndPairsWithoutAPose) {
  const std::string d = flown_dataset();
  // Four sequences with the right frame of sequence 6 missing, and no pose row for sequence 3.
  {
    std::ofstream idx(d + "/D/frames/index_gaps.csv");
    for (const std::string& l : read_lines(d + "/D/frames/index.csv")) {
      const bool keep = l.rfind("0,", 0) == 0 || l.rfind("3,", 0) == 0 || l.rfind("6,0,", 0) == 0 ||
                        l.rfind("9,", 0) == 0 || l.rfind("sequence", 0) == 0 || l.rfind("#", 0) == 0;
      if (keep) idx << l << "\n";
    }
    std::ofstream poses(d + "/P/poses_gap.csv");
    for (const std::string& l : read_lines(d + "/P/poses.csv"))
      if (l.rfind("3,0,", 0) != 0) poses << l << "\n";
  }
  std::string log;
  ASSERT_EQ(augrig("augment --rig " + d + "/D/rig.yaml --frames " + d + "/D/frames/index_gaps.csv --poses " +
                       d + "/P/poses_gap.csv --out " + d + "/G",
                   &log),
            0)
      << log;
  EXPECT_NE(log.find("frames read: left 4, right 3 = 2 x 3 pairs + 1 unpaired"), std::string::npos) << log;
  EXPECT_NE(log.find("Frames without a partner (not augmented): left 1, right 0"), std::string::npos) << log;
  EXPECT_NE(log.find("Pairs without a pose (not augmented): 1"), std::string::npos) << log;
  EXPECT_NE(log.find("no left-camera row at t_ns"), std::string::npos) << log;  // which one, on stderr
  EXPECT_NE(log.find("Wrote 2 stereo frame(s)"), std::string::npos) << log;
  EXPECT_EQ(read_lines(fs::path(d) / "G" / "stats.csv").size(), 3u);
  EXPECT_FALSE(fs::exists(fs::path(d) / "G" / "left" / "mask" / "000003.png"));
  EXPECT_TRUE(fs::exists(fs::path(d) / "G" / "left" / "mask" / "000009.png"));
}

TEST(Augment, IndexedImagesOfAnotherSizeThanTheRigFailAtOnceWithOneMessage) {
  const std::string d = flown_dataset();
  const std::string dir = output_dir("augment_index_size");
  fs::create_directories(dir + "/left");
  fs::create_directories(dir + "/right");
  ASSERT_TRUE(cv::imwrite(dir + "/left/a.png", pattern(640, 480, CV_8UC3, 0)));
  ASSERT_TRUE(cv::imwrite(dir + "/right/a.png", pattern(640, 480, CV_8UC3, 1)));
  std::ofstream(dir + "/index.csv")
      << "sequence,camera,t_ns,file\n0,0,1000,left/a.png\n0,1,1000,right/a.png\n";
  std::string out;
  EXPECT_EQ(augrig("augment --rig " + d + "/D/rig.yaml --frames " + dir + "/index.csv --poses " + d +
                       "/P/poses.csv --out " + dir + "/out",
                   &out),
            1)
      << out;
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << "one line:\n" << out;
  EXPECT_NE(out.find(dir + "/index.csv:2 (camera 0, sequence 0)"), std::string::npos) << out;
  EXPECT_NE(out.find("640x480"), std::string::npos) << out;
  EXPECT_NE(out.find("1280x960"), std::string::npos) << out;
  // The flags say what is missing or in conflict (exit 2).
  EXPECT_EQ(augrig("augment --rig default --frames " + dir + "/index.csv --out " + dir + "/out", &out), 2)
      << out;
  EXPECT_NE(out.find("--scene"), std::string::npos) << out;
  EXPECT_EQ(augrig("augment --rig default --frames " + dir + "/index.csv --left x --poses p --out o", &out),
            2)
      << out;
}

// ---- demo ----------------------------------------------------------------------------------------

TEST(Demo, SixFramesWriteStatsAndContactSheet) {
  const std::string dir = output_dir("demo_six_frames");
  std::string log;
  ASSERT_EQ(augrig("demo --frames 6 --out " + dir, &log), 0) << log;
  const auto lines = read_lines(fs::path(dir) / "stats.csv");
  ASSERT_EQ(lines.size(), 7u) << log;
  EXPECT_EQ(lines[0], kCsvHeader);
  const cv::Mat sheet = cv::imread(dir + "/demo.png", cv::IMREAD_UNCHANGED);
  EXPECT_EQ(sheet.size(), cv::Size(1280, 960));
  // Images for frame 0 and the last frame only.
  EXPECT_TRUE(fs::exists(dir + "/left/augmented/frame_0000.png"));
  EXPECT_TRUE(fs::exists(dir + "/left/augmented/frame_0005.png"));
  EXPECT_FALSE(fs::exists(dir + "/left/augmented/frame_0003.png"));
  EXPECT_NE(log.find("Run summary over 6"), std::string::npos) << log;
  EXPECT_NE(log.find("ms per stereo frame"), std::string::npos) << log;
  // The scene came from nav fusion of the simulated logs, and the demo says how good it was.
  EXPECT_TRUE(fs::exists(dir + "/nav/tanker/gps.nmea"));
  EXPECT_TRUE(fs::exists(dir + "/poses.csv"));
  EXPECT_TRUE(fs::exists(dir + "/truth_poses.csv"));
  const auto at = log.find("Nav against truth (receiver in each camera): 12 frames: position RMS ");
  ASSERT_NE(at, std::string::npos) << log;
  const double rms_mm = std::stod(log.substr(at + 70));
  EXPECT_LT(rms_mm, 20.0) << log;
}

TEST(Demo, RecordsWhatItAugmentedAndTheRecordingChecksClean) {
  const std::string dir = output_dir("demo_record");
  std::string log;
  ASSERT_EQ(augrig("demo --frames 4 --out " + dir + "/out --record " + dir + "/rec", &log), 0) << log;
  EXPECT_NE(log.find("Recording: "), std::string::npos) << log;
  EXPECT_NE(log.find("4 stereo frames"), std::string::npos) << log;
  std::string check;
  EXPECT_EQ(augrig("check " + dir + "/rec", &check), 0) << check;
  EXPECT_NE(check.find("frames: 4 (4 intact, 4 augmented, 4 with masks, 4 with statistics)"),
            std::string::npos)
      << check;
  EXPECT_NE(check.find("tanker.gps"), std::string::npos) << check;
  EXPECT_NE(check.find("problems: none"), std::string::npos) << check;
  // The recorded augmented frame is the one the demo wrote as PNG: the last frame (index 3).
  auto rec = recorder::RecordingReader::open(dir + "/rec");
  ASSERT_TRUE(rec) << rec.error().message;
  auto last = (*rec)->read_frame(3);
  ASSERT_TRUE(last) << last.error().message;
  const cv::Mat png = cv::imread(dir + "/out/left/augmented/frame_0003.png", cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(png.empty());
  const Image& aug = last->augmented[0];
  ASSERT_EQ(aug.width(), png.cols);
  std::size_t differ = 0;
  for (int y = 0; y < png.rows; ++y)
    for (int x = 0; x < png.cols; ++x)
      for (int c = 0; c < 3; ++c) differ += aug.row(y)[3 * x + c] != png.ptr<std::uint8_t>(y)[3 * x + 2 - c];
  EXPECT_EQ(differ, 0u);
}

}  // namespace
}  // namespace augrig
