// The KITTI and Middlebury sinks, read back as those benchmarks' tools read them: images with
// OpenCV's imread, Middlebury's PFM with a small reader written here, the calibration files
// parsed by their keys. Oracles: OpenCV's own rectification from the calibration file's K, D,
// R_rect and P_rect (the images), the augmenter's raw receiver depth (every true disparity, carried
// back through the file's calibration to a raw pixel, gives that pixel's depth), the stereo
// classes (the non-occluded pixels), and the KITTI and Middlebury truths against each other.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "eval/benchmark_layout.hpp"
#include "pipeline/pipeline.hpp"
#include "pipeline/report.hpp"
#include "pipeline/sinks/registry.hpp"
#include "pipeline/sinks/sinks.hpp"
#include "tests/support/pipeline_parts.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::pipeline {
namespace {

namespace fs = std::filesystem;

const std::string kScenario = "sim://" + test::data_path("scenarios/short_approach.yaml") + "?every=4&rate=0";

// KITTI's calib_cam_to_cam.txt: "KEY: v v v ...".
std::map<std::string, std::vector<double>> read_kitti_calib(const fs::path& file) {
  std::map<std::string, std::vector<double>> m;
  std::ifstream in(file);
  for (std::string line; std::getline(in, line);) {
    const auto colon = line.find(':');
    std::istringstream v(line.substr(colon + 1));
    std::vector<double> values;
    for (double x; v >> x;) values.push_back(x);
    m[line.substr(0, colon)] = values;
  }
  return m;
}

// Middlebury's calib.txt: "key=value".
std::map<std::string, std::string> read_middlebury_calib(const fs::path& file) {
  std::map<std::string, std::string> m;
  std::ifstream in(file);
  for (std::string line; std::getline(in, line);) {
    const auto eq = line.find('=');
    if (eq != std::string::npos) m[line.substr(0, eq)] = line.substr(eq + 1);
  }
  return m;
}

// A PFM file as its definition reads: "Pf", width height, scale (< 0: little endian), rows
// bottom to top.
cv::Mat read_pfm(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::string magic;
  int w = 0, h = 0;
  double scale = 0;
  in >> magic >> w >> h >> scale;
  in.get();  // the single whitespace before the data
  EXPECT_EQ(magic, "Pf");
  EXPECT_LT(scale, 0.0);
  cv::Mat m(h, w, CV_32FC1);
  for (int y = h - 1; y >= 0; --y) in.read(reinterpret_cast<char*>(m.ptr<float>(y)), w * 4);
  EXPECT_TRUE(in) << file;
  EXPECT_EQ(in.peek(), EOF) << file;
  return m;
}

cv::Mat mat3(const std::vector<double>& v) {
  return cv::Mat(3, 3, CV_64F, const_cast<double*>(v.data())).clone();
}

struct Seen {
  StereoFrame raw;
  DepthImage depth_left;
};

// Five pairs of the short approach through both sinks, and what the augmenter made of each.
struct BothRun {
  std::string dir;
  Rig rig;
  std::vector<Seen> seen;
  std::vector<std::string> outputs;
};

BothRun run_both(const std::string& name) {
  BothRun r;
  r.dir = test::output_dir(name);
  fs::remove_all(r.dir);
  PipelineParts p = test::pipeline_parts(kScenario);
  p.max_pairs = 5;
  r.rig = p.rig;
  for (const char* layout : {"kitti", "middlebury"}) {
    auto sink = make_sink(std::string(layout) + ":" + r.dir + "/" + layout, {p.rig});
    EXPECT_TRUE(sink) << sink.error().message;
    p.sinks.push_back(std::move(*sink));
  }
  p.sinks.push_back(make_callback_sink(
      [&r](const StereoFrame& raw, const StereoResult& result, const SceneState&, const FramePoses&) {
        r.seen.push_back({raw, result.left.receiver_depth});
        return Status{};
      }));
  Pipeline pipeline(std::move(p));
  std::ostringstream o, e;
  auto report = pipeline.run(o, e);
  EXPECT_TRUE(report) << report.error().message;
  if (report) r.outputs = report->outputs;
  return r;
}

TEST(StereoBenchmarkSink, KittiFilesAreWhatKittisToolsReadAndAgreeWithTheAugmentersDepth) {
  const BothRun run = run_both("stereo_benchmark_kitti");
  ASSERT_EQ(run.seen.size(), 5u);
  ASSERT_EQ(run.outputs.size(), 2u);
  EXPECT_NE(run.outputs[0].find("kitti: 5 stereo pair(s) in the KITTI layout"), std::string::npos)
      << run.outputs[0];
  const fs::path k = fs::path(run.dir) / "kitti";
  EXPECT_FALSE(fs::exists(k / "INCOMPLETE"));
  auto calib = read_kitti_calib(k / "calib_cam_to_cam.txt");
  for (const char* key :
       {"S_02", "K_02", "D_02", "R_03", "T_03", "R_rect_02", "R_rect_03", "P_rect_02", "P_rect_03"})
    ASSERT_TRUE(calib.count(key)) << key;
  // The right camera's place: R_03, T_03 are the rig's T_right_left.
  const Pose T_rl = run.rig.T_right_left();
  EXPECT_NEAR(calib["T_03"][0], T_rl.translation_m.x(), 1e-9);
  EXPECT_NEAR(calib["T_03"][2], T_rl.translation_m.z(), 1e-9);
  const std::vector<double>& P2 = calib["P_rect_02"];
  const std::vector<double>& P3 = calib["P_rect_03"];
  const double f = P2[0], cx = P2[2], cy = P2[6], fB = -P3[3];
  EXPECT_EQ(P2[3], 0.0);
  EXPECT_NEAR(fB / f, T_rl.translation_m.norm(), 1e-9);

  // OpenCV's own rectification of the raw left image from the file's K, D, R_rect, P_rect.
  const CameraModel& left = run.rig.left().model;
  cv::Mat map1, map2;
  cv::initUndistortRectifyMap(
      mat3(calib["K_02"]), cv::Mat(calib["D_02"]).clone(), mat3(calib["R_rect_02"]),
      cv::Mat(3, 4, CV_64F, const_cast<double*>(P2.data())).colRange(0, 3).clone(),
      cv::Size(static_cast<int>(calib["S_rect_02"][0]), static_cast<int>(calib["S_rect_02"][1])), CV_32FC1,
      map1, map2);
  const Eigen::Matrix3d R_rect =
      Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(calib["R_rect_02"].data());
  std::int64_t checked = 0, agree = 0;
  for (std::size_t i = 0; i < run.seen.size(); ++i) {
    char id[32];
    std::snprintf(id, sizeof id, "%06zu_10.png", i);
    const cv::Mat raw_rect = cv::imread((k / "raw/training/image_2" / id).string(), cv::IMREAD_UNCHANGED);
    const cv::Mat aug_rect =
        cv::imread((k / "augmented/training/image_2" / id).string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(raw_rect.empty()) << id;
    cv::Mat want;
    cv::remap(bgr_of(run.seen[i].raw.left.image.view()), want, map1, map2, cv::INTER_LINEAR);
    cv::Mat diff;
    cv::absdiff(raw_rect, want, diff);
    EXPECT_LT(cv::mean(diff)[0], 0.5) << id;
    // The boom is in the augmented tree only, where its mask says.
    const cv::Mat boom =
        cv::imread((k / "augmented/training/boom_mask_0" / id).string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(boom.type(), CV_8UC1);
    cv::absdiff(raw_rect, aug_rect, diff);
    cv::Mat changed;
    cv::cvtColor(diff, changed, cv::COLOR_BGR2GRAY);
    EXPECT_GT(cv::countNonZero((changed > 8) & (boom & 1)), 100) << id;

    // Every true disparity, back through the file's calibration to a raw pixel: the augmenter's
    // depth there is the point's.
    const cv::Mat disp =
        cv::imread((k / "augmented/training/disp_occ_0" / id).string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(disp.type(), CV_16UC1);
    EXPECT_TRUE(fs::equivalent(k / "augmented/training/disp_occ_0" / id, k / "raw/training/disp_occ_0" / id));
    const DepthImage& depth = run.seen[i].depth_left;
    for (int y = 0; y < disp.rows; y += 3)
      for (int x = 0; x < disp.cols; x += 3) {
        const std::uint16_t v = disp.at<std::uint16_t>(y, x);
        if (!v) continue;
        const double d = v / 256.0, z = fB / d;
        const Eigen::Vector3d p_rect((x - cx) * z / f, (y - cy) * z / f, z);
        const Eigen::Vector3d p_raw = R_rect.transpose() * p_rect;
        const auto uv = left.project(p_raw);
        if (!uv) continue;
        const int u = static_cast<int>(std::lround(uv->x())), w = static_cast<int>(std::lround(uv->y()));
        if (u < 0 || w < 0 || u >= depth.width || w >= depth.height || !std::isfinite(depth.at(u, w)))
          continue;
        ++checked;
        agree += std::abs(depth.at(u, w) - p_raw.z()) < 0.01 * p_raw.z();
      }
  }
  ASSERT_GT(checked, 2000);
  EXPECT_GT(static_cast<double>(agree) / checked, 0.98) << agree << " of " << checked;

  // The non-occluded truth: the receiver pixels of stereo class "both", as frames.csv counts them.
  std::ifstream frames(k / "frames.csv");
  std::string line;
  std::getline(frames, line);
  std::getline(frames, line);
  for (int i = 0; std::getline(frames, line); ++i) {
    std::vector<std::int64_t> v;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) v.push_back(std::stoll(c));
    ASSERT_EQ(v.size(), 5u);
    char id[32];
    std::snprintf(id, sizeof id, "%06d_10.png", i);
    const cv::Mat occ = cv::imread((k / "augmented/training/disp_occ_0" / id).string(), cv::IMREAD_UNCHANGED);
    const cv::Mat noc = cv::imread((k / "augmented/training/disp_noc_0" / id).string(), cv::IMREAD_UNCHANGED);
    const cv::Mat cls =
        cv::imread((k / "augmented/training/stereo_class_0" / id).string(), cv::IMREAD_UNCHANGED);
    EXPECT_EQ(cv::countNonZero(occ), v[3]) << id;
    EXPECT_EQ(cv::countNonZero(noc), v[4]) << id;
    EXPECT_EQ(cv::countNonZero((noc != 0) & (cls != static_cast<int>(StereoClass::kBoth))), 0) << id;
    EXPECT_EQ(v[0], i);
    EXPECT_EQ(v[1], run.seen[static_cast<std::size_t>(i)].raw.t_key_ns);
  }
}

TEST(StereoBenchmarkSink, MiddleburyFilesHoldTheSameTruthAsKittis) {
  const BothRun run = run_both("stereo_benchmark_middlebury");
  ASSERT_EQ(run.seen.size(), 5u);
  const fs::path m = fs::path(run.dir) / "middlebury", k = fs::path(run.dir) / "kitti";
  const auto kc = read_kitti_calib(k / "calib_cam_to_cam.txt");
  std::int64_t receiver_px = 0;
  for (int i = 0; i < 5; ++i) {
    char id[32], kid[32];
    std::snprintf(id, sizeof id, "%06d", i);
    std::snprintf(kid, sizeof kid, "%06d_10.png", i);
    for (const char* f : {"im0.png", "im1.png", "calib.txt", "disp0GT.pfm", "mask0nocc.png"}) {
      EXPECT_TRUE(fs::exists(m / "raw" / id / f)) << id << "/" << f;
      EXPECT_TRUE(fs::exists(m / "augmented" / id / f)) << id << "/" << f;
    }
    EXPECT_TRUE(fs::equivalent(m / "raw" / id / "disp0GT.pfm", m / "augmented" / id / "disp0GT.pfm"));
    // The same rectified images as KITTI's.
    for (const char* tree : {"raw", "augmented"}) {
      const cv::Mat a = cv::imread((m / tree / id / "im1.png").string(), cv::IMREAD_UNCHANGED);
      const cv::Mat b = cv::imread((k / tree / "training/image_3" / kid).string(), cv::IMREAD_UNCHANGED);
      ASSERT_EQ(a.size(), b.size());
      EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0) << tree << " " << id;
    }
    const cv::Mat gt = read_pfm(m / "augmented" / id / "disp0GT.pfm");
    const cv::Mat kd = cv::imread((k / "augmented/training/disp_occ_0" / kid).string(), cv::IMREAD_UNCHANGED);
    const cv::Mat nocc = cv::imread((m / "augmented" / id / "mask0nocc.png").string(), cv::IMREAD_UNCHANGED);
    const cv::Mat knoc =
        cv::imread((k / "augmented/training/disp_noc_0" / kid).string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(gt.size(), kd.size());
    double vmin = 1e9, vmax = -1e9;
    for (int y = 0; y < gt.rows; ++y)
      for (int x = 0; x < gt.cols; ++x) {
        const float g = gt.at<float>(y, x);
        const std::uint16_t kv = kd.at<std::uint16_t>(y, x);
        if (std::isinf(g)) {
          ASSERT_EQ(kv, 0) << x << "," << y;
          ASSERT_EQ(nocc.at<std::uint8_t>(y, x), 0);
          continue;
        }
        ++receiver_px;
        ASSERT_NEAR(kv / 256.0, g, 1.0 / 512 + 1e-6) << x << "," << y;
        ASSERT_EQ(nocc.at<std::uint8_t>(y, x), knoc.at<std::uint16_t>(y, x) ? 255 : 128) << x << "," << y;
        vmin = std::min<double>(vmin, g), vmax = std::max<double>(vmax, g);
      }
    auto calib = read_middlebury_calib(m / "augmented" / id / "calib.txt");
    for (const char* key :
         {"cam0", "cam1", "doffs", "baseline", "width", "height", "ndisp", "isint", "vmin", "vmax"})
      ASSERT_TRUE(calib.count(key)) << key;
    EXPECT_EQ(std::stoi(calib["width"]), gt.cols);
    EXPECT_EQ(std::stoi(calib["height"]), gt.rows);
    EXPECT_EQ(std::stod(calib["doffs"]), 0.0);
    // Middlebury's Z = baseline * f / (d + doffs) is KITTI's f B / d, baseline in mm.
    EXPECT_NEAR(std::stod(calib["baseline"]) * 1e-3 * kc.at("P_rect_02")[0], -kc.at("P_rect_03")[3], 1e-6);
    EXPECT_EQ(calib["cam0"], calib["cam1"]);
    EXPECT_EQ(std::stoi(calib["ndisp"]) % 16, 0);
    if (vmax > vmin) {
      EXPECT_LE(std::stod(calib["vmin"]), vmin);
      EXPECT_GE(std::stod(calib["vmax"]), vmax);
      EXPECT_GT(std::stoi(calib["ndisp"]), vmax);
    }
  }
  EXPECT_GT(receiver_px, 5000);
}

TEST(StereoBenchmarkSink, BadArgumentsAndAFolderHoldingAnExportAreNamed) {
  const Rig rig = Rig::paper_default();
  const std::string dir = test::output_dir("stereo_benchmark_bad");
  fs::remove_all(dir);
  auto opts = make_sink("kitti:" + dir + "/a,no-masks", {rig});
  ASSERT_FALSE(opts);
  EXPECT_EQ(opts.error().message, "--sink kitti:" + dir + "/a,no-masks: expected kitti:DIR (no options)");
  {
    auto first = make_sink("middlebury:" + dir + "/m", {rig});
    ASSERT_TRUE(first) << first.error().message;
    PipelineReport report;
    ASSERT_TRUE((*first)->close(report));
    EXPECT_NE(report.outputs.at(0).find("0 stereo pair(s) in the Middlebury layout"), std::string::npos);
  }
  auto again = make_sink("middlebury:" + dir + "/m", {rig});
  ASSERT_FALSE(again);
  EXPECT_EQ(
      again.error().message,
      "middlebury sink: " + dir + "/m: holds a benchmark export already (frames.csv); expected a new folder");
  auto unwritable = make_sink("kitti:/proc/augrig-kitti", {rig});
  ASSERT_FALSE(unwritable);
  EXPECT_EQ(unwritable.error().message.rfind("kitti sink: /proc/augrig-kitti: cannot create the folder", 0),
            0u)
      << unwritable.error().message;
  // A pair without an augmentation is left out and counted.
  auto sink = make_sink("kitti:" + dir + "/k", {rig});
  ASSERT_TRUE(sink) << sink.error().message;
  StereoFrame raw;
  FramePoses poses;
  PairContext pair{.raw = raw, .result = nullptr, .scene = nullptr, .poses = poses, .pair = 1};
  ASSERT_TRUE((*sink)->consume(pair));
  PipelineReport report;
  ASSERT_TRUE((*sink)->close(report));
  EXPECT_NE(report.outputs.at(0).find("0 stereo pair(s) in the KITTI layout"), std::string::npos);
  EXPECT_NE(report.outputs.at(0).find("1 pair(s) without an augmentation left out"), std::string::npos);
  EXPECT_FALSE(fs::exists(dir + "/k/INCOMPLETE"));
}

// A pair that cannot be written (a file stands where its folder goes) stops the run with the path,
// and the folder keeps its INCOMPLETE marker: half a dataset is never taken for a whole one.
TEST(StereoBenchmarkSink, AFailedRunLeavesTheFolderIncomplete) {
  const std::string dir = test::output_dir("stereo_benchmark_failed");
  fs::remove_all(dir);
  PipelineParts p = test::pipeline_parts(kScenario);
  p.max_pairs = 2;
  auto sink = make_sink("kitti:" + dir + "/k", {p.rig});
  ASSERT_TRUE(sink) << sink.error().message;
  std::ofstream(dir + "/k/augmented") << "in the way";
  p.sinks.push_back(std::move(*sink));
  Pipeline pipeline(std::move(p));
  std::ostringstream o, e;
  auto report = pipeline.run(o, e);
  ASSERT_FALSE(report);
  EXPECT_NE(report.error().message.find("kitti sink: " + dir + "/k/augmented"), std::string::npos)
      << report.error().message;
  EXPECT_TRUE(fs::exists(dir + "/k/INCOMPLETE"));
}

}  // namespace
}  // namespace augrig::pipeline
