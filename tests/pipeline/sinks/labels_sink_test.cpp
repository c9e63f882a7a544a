// The COCO and YOLO label sinks, read back as their users' tools read them: annotations.json
// parsed as JSON, its uncompressed RLE decoded here (column-major runs from a 0 run, as
// pycocotools' frPyObjects/decode take it), the YOLO text files split into numbers. Oracles: the
// augmenter's own masks of each pair (every decoded mask, box and area), OpenCV's projectPoints
// (every keypoint's position) and the mask bits at each keypoint's deciding pixel (a visible
// keypoint on a receiver-only pixel, a boom-hidden one on the boom). The scenes cycle through
// contact and swung booms so that the boom and the receiver each hide some keypoints.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>

#include "core/conventions.hpp"
#include "pipeline/pipeline.hpp"
#include "pipeline/report.hpp"
#include "pipeline/sinks/registry.hpp"
#include "pipeline/sinks/sinks.hpp"
#include "render/boom_control.hpp"
#include "render/keypoints.hpp"
#include "render/models.hpp"
#include "tests/support/pipeline_parts.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::pipeline {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const std::string kScenario = "sim://" + test::data_path("scenarios/short_approach.yaml") + "?every=4&rate=0";

// The scenes the pairs cycle through: the receptacle under the nozzle, then the receiver moved
// about under booms swung over it (the keypoints test's cases).
class CyclingScenes final : public PoseProvider {
 public:
  explicit CyclingScenes(const Rig& rig) {
    const Eigen::Vector3d receptacle = rig.receiver.receptacle_m;
    const std::vector<std::pair<BoomArticulation, Eigen::Vector3d>> cases = {
        {{0.52, 0.0, 3.0}, {0, 0, 0}},
        {{0.52, 0.03, 3.0}, {-2.0, 0.5, 0.5}},
        {{0.45, -0.15, 2.0}, {-3.0, 1.5, 1.0}},
        {{0.50, 0.2, 1.0}, {1.0, -7.0, 2.0}},
        {{0.40, 0.0, 0.0}, {-6.0, 0.0, 3.0}}};
    for (const auto& [a, offset] : cases) {
      SceneState s = scene_at_contact(rig, BoomDimensions{}, receptacle, a);
      s.T_body_receiver.translation_m += offset;
      scenes_.push_back(s);
    }
  }
  std::string describe() const override { return "the test's scenes"; }
  FramePoses at(const StereoFrame&, TimestampNs) override {
    FramePoses p;
    p.scene = scenes_[next_++ % scenes_.size()];
    p.boom_given = true;
    return p;
  }

 private:
  std::vector<SceneState> scenes_;
  std::size_t next_ = 0;
};

struct Seen {
  Image mask[2];
  SceneState scene;
};

struct LabelRun {
  std::string dir;
  Rig rig;
  std::vector<Seen> seen;
  std::vector<std::string> outputs;
};

// `pairs` pairs of the short approach under the cycling scenes, into each of `specs` (SCHEME:SUBDIR).
LabelRun run_labels(const std::string& name, const std::vector<std::string>& specs, int pairs = 5,
                    const Rig* rig = nullptr) {
  LabelRun r;
  r.dir = test::output_dir(name);
  PipelineParts p = test::pipeline_parts(kScenario);
  if (rig) p.rig = *rig;
  p.max_pairs = static_cast<std::uint64_t>(pairs);
  p.poses = std::make_unique<CyclingScenes>(p.rig);
  p.augment.look = Look::kPlain;
  r.rig = p.rig;
  for (const std::string& spec : specs) {
    const auto colon = spec.find(':');
    auto sink = make_sink(spec.substr(0, colon + 1) + r.dir + "/" + spec.substr(colon + 1), {p.rig});
    EXPECT_TRUE(sink) << sink.error().message;
    if (sink) p.sinks.push_back(std::move(*sink));
  }
  p.sinks.push_back(make_callback_sink(
      [&r](const StereoFrame&, const StereoResult& result, const SceneState& scene, const FramePoses&) {
        r.seen.push_back({{result.left.mask, result.right.mask}, scene});
        return Status{};
      }));
  Pipeline pipeline(std::move(p));
  std::ostringstream o, e;
  auto report = pipeline.run(o, e);
  EXPECT_TRUE(report) << report.error().message;
  if (report) r.outputs = report->outputs;
  return r;
}

json read_json(const fs::path& file) {
  std::ifstream in(file);
  return json::parse(in);
}

// COCO's uncompressed RLE decoded: counts alternate 0s and 1s from a run of 0s, column by column.
std::vector<std::uint8_t> decode_rle(const json& rle, int& width, int& height) {
  height = rle["size"][0].get<int>();
  width = rle["size"][1].get<int>();
  std::vector<std::uint8_t> m(static_cast<std::size_t>(width) * height, 0);
  std::size_t at = 0;
  bool one = false;
  for (const json& c : rle["counts"]) {
    const auto n = c.get<std::size_t>();
    for (std::size_t i = 0; i < n && at < m.size(); ++i, ++at) {
      const std::size_t x = at / static_cast<std::size_t>(height), y = at % static_cast<std::size_t>(height);
      m[y * static_cast<std::size_t>(width) + x] = one;
    }
    one = !one;
  }
  EXPECT_EQ(at, m.size()) << "the runs cover the image";
  return m;
}

// The pixels of a mask image for which `pick` holds.
template <typename Pick>
std::vector<std::uint8_t> pixels_of(const Image& mask, Pick&& pick) {
  std::vector<std::uint8_t> v(static_cast<std::size_t>(mask.width()) * mask.height());
  for (int y = 0; y < mask.height(); ++y)
    for (int x = 0; x < mask.width(); ++x)
      v[static_cast<std::size_t>(y) * mask.width() + x] = pick(mask.row(y)[x]);
  return v;
}

// [x, y, w, h] of the set pixels, and their count.
std::pair<std::vector<int>, std::int64_t> box_of(const std::vector<std::uint8_t>& m, int width) {
  int x0 = width, y0 = 1 << 30, x1 = -1, y1 = -1;
  std::int64_t n = 0;
  for (std::size_t i = 0; i < m.size(); ++i)
    if (m[i]) {
      const int x = static_cast<int>(i % width), y = static_cast<int>(i / width);
      x0 = std::min(x0, x), y0 = std::min(y0, y), x1 = std::max(x1, x), y1 = std::max(y1, y);
      ++n;
    }
  return {{x0, y0, x1 - x0 + 1, y1 - y0 + 1}, n};
}

// keypoints.csv rows by (image, keypoint).
std::map<std::pair<std::string, std::string>, std::vector<std::string>> read_keypoints_csv(
    const fs::path& f) {
  std::map<std::pair<std::string, std::string>, std::vector<std::string>> rows;
  std::ifstream in(f);
  std::string line;
  std::getline(in, line);  // the comment
  std::getline(in, line);
  EXPECT_EQ(line, "image,camera,t_ns,keypoint,u_px,v_px,class,decided_x,decided_y,coco_v");
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream s(line);
    for (std::string c; std::getline(s, c, ',');) cells.push_back(c);
    if (line.back() == ',') cells.emplace_back();
    EXPECT_EQ(cells.size(), 10u) << line;
    rows[{cells[0], cells[3]}] = cells;
  }
  return rows;
}

TEST(LabelsSink, CocoMasksAreTheAugmentersAndKeypointsLieWhereOpenCVProjectsThem) {
  const LabelRun run = run_labels("labels_coco", {"coco:coco"}, 10);
  ASSERT_EQ(run.seen.size(), 10u);
  ASSERT_EQ(run.outputs.size(), 1u);
  EXPECT_NE(run.outputs[0].find("20 image(s) of 10 pair(s) labelled in COCO's keypoint format"),
            std::string::npos)
      << run.outputs[0];
  const fs::path dir = fs::path(run.dir) / "coco";
  EXPECT_FALSE(fs::exists(dir / "INCOMPLETE"));
  const json coco = read_json(dir / "annotations.json");
  const auto csv = read_keypoints_csv(dir / "keypoints.csv");
  // The receiver's category names the keypoints, in the defaults' order; the boom has none.
  Eigen::Vector3d receptacle;
  const Model receiver = make_builtin_receiver(&receptacle);
  const std::vector<Keypoint> keypoints = default_receiver_keypoints(receiver, receptacle);
  ASSERT_EQ(coco["categories"].size(), 2u);
  EXPECT_EQ(coco["categories"][0]["name"], "receiver");
  ASSERT_EQ(coco["categories"][0]["keypoints"].size(), keypoints.size());
  for (std::size_t k = 0; k < keypoints.size(); ++k)
    EXPECT_EQ(coco["categories"][0]["keypoints"][k], keypoints[k].name);
  for (const json& edge : coco["categories"][0]["skeleton"])
    for (const json& i : edge) EXPECT_TRUE(i.get<int>() >= 1 && i.get<int>() <= 10);
  EXPECT_EQ(coco["categories"][1]["name"], "boom");
  ASSERT_EQ(coco["images"].size(), 20u);

  std::map<std::int64_t, std::vector<json>> by_image;
  std::set<std::int64_t> ids;
  for (const json& a : coco["annotations"]) {
    EXPECT_TRUE(ids.insert(a["id"].get<std::int64_t>()).second) << "annotation ids are unique";
    by_image[a["image_id"].get<std::int64_t>()].push_back(a);
  }
  std::map<int, int> flags;
  int checked_pixels = 0;
  for (std::size_t i = 0; i < 20; ++i) {
    const json& image = coco["images"][i];
    const std::size_t pair = i / 2;
    const int c = static_cast<int>(i % 2);
    EXPECT_EQ(image["file_name"], "images/" + std::string(6 - std::to_string(pair).size(), '0') +
                                      std::to_string(pair) + (c ? "_right.png" : "_left.png"));
    const cv::Mat png =
        cv::imread((dir / image["file_name"].get<std::string>()).string(), cv::IMREAD_UNCHANGED);
    EXPECT_EQ(png.cols, image["width"].get<int>());
    EXPECT_EQ(png.rows, image["height"].get<int>());
    const Image& mask = run.seen[pair].mask[c];
    const RigCamera& cam = run.rig.cameras[static_cast<std::size_t>(c)];
    for (const json& a : by_image[image["id"].get<std::int64_t>()]) {
      const bool is_receiver = a["category_id"] == 1;
      // The instance's mask, box and area are the augmenter's mask bits.
      int w = 0, h = 0;
      const auto decoded = decode_rle(a["segmentation"], w, h);
      ASSERT_EQ(w, mask.width());
      ASSERT_EQ(h, mask.height());
      const auto want =
          is_receiver
              ? pixels_of(mask, [](std::uint8_t m) { return (m & kMaskReceiver) && !(m & kMaskBoom); })
              : pixels_of(mask, [](std::uint8_t m) { return (m & kMaskBoom) != 0; });
      ASSERT_EQ(decoded, want) << "image " << i << (is_receiver ? " receiver" : " boom");
      const auto [bbox, area] = box_of(want, w);
      EXPECT_EQ(a["bbox"].get<std::vector<int>>(), bbox);
      EXPECT_EQ(a["area"].get<std::int64_t>(), area);
      checked_pixels += 1;
      if (!is_receiver) continue;
      int aw = 0, ah = 0;
      EXPECT_EQ(decode_rle(a["augrig_amodal_segmentation"], aw, ah),
                pixels_of(mask, [](std::uint8_t m) { return (m & kMaskReceiver) != 0; }));
      // Each keypoint where OpenCV projects it, its flag as its class says, and its deciding pixel's
      // mask bits as its class says.
      const Pose T_cam_receiver = cam.T_body_cam.inverse() * run.seen[pair].scene.T_body_receiver;
      const cv::Matx33d K(cam.model.fx_px, 0, cam.model.cx_px, 0, cam.model.fy_px, cam.model.cy_px, 0, 0, 1);
      ASSERT_EQ(a["keypoints"].size(), 3 * keypoints.size());
      int labelled = 0;
      for (std::size_t k = 0; k < keypoints.size(); ++k) {
        const Eigen::Vector3d p = T_cam_receiver * keypoints[k].p_receiver_m;
        std::vector<cv::Point2d> uv;
        cv::projectPoints(std::vector<cv::Point3d>{{p.x(), p.y(), p.z()}}, cv::Vec3d(0, 0, 0),
                          cv::Vec3d(0, 0, 0), K, cv::noArray(), uv);
        const int v = a["keypoints"][3 * k + 2].get<int>();
        const std::string cls = a["augrig_keypoint_classes"][k].get<std::string>();
        ++flags[v];
        labelled += v > 0;
        const auto& row = csv.at({image["file_name"].get<std::string>(), keypoints[k].name});
        EXPECT_EQ(row[6], cls);
        EXPECT_EQ(std::stoi(row[9]), v);
        ASSERT_TRUE(p.z() > 0);
        EXPECT_NEAR(a["augrig_keypoints_projected"][k][0].get<double>(), uv[0].x, 0.006);
        EXPECT_NEAR(a["augrig_keypoints_projected"][k][1].get<double>(), uv[0].y, 0.006);
        EXPECT_NEAR(std::stod(row[4]), uv[0].x, 0.0006);
        if (v == 0) {
          EXPECT_TRUE(cls == "outside" || cls == "not_drawn") << cls;
          EXPECT_EQ(a["keypoints"][3 * k].get<double>(), 0.0);
          continue;
        }
        EXPECT_NEAR(a["keypoints"][3 * k].get<double>(), uv[0].x, 0.006);
        EXPECT_NEAR(a["keypoints"][3 * k + 1].get<double>(), uv[0].y, 0.006);
        const int dx = std::stoi(row[7]), dy = std::stoi(row[8]);
        EXPECT_LE(std::abs(dx - uv[0].x), 1.5);
        EXPECT_LE(std::abs(dy - uv[0].y), 1.5);
        const std::uint8_t m = mask.row(dy)[dx];
        if (cls == "visible") {
          EXPECT_EQ(m & (kMaskReceiver | kMaskBoom), kMaskReceiver) << keypoints[k].name << ": visible off the receiver";
        }
        if (cls == "hidden_by_boom") {
          EXPECT_TRUE(m & kMaskBoom) << keypoints[k].name;
        }
        if (cls == "hidden_by_receiver") {
          EXPECT_TRUE(m & kMaskReceiver) << keypoints[k].name;
        }
        EXPECT_EQ(v, cls == "visible" ? 2 : 1) << cls;
      }
      EXPECT_EQ(a["num_keypoints"].get<int>(), labelled);
    }
  }
  // Every kind of flag among the cases, and the boom in most images.
  EXPECT_GT(flags[2], 40);
  EXPECT_GT(flags[1], 2);
  EXPECT_GT(checked_pixels, 30);
}

TEST(LabelsSink, YoloLabelsAreTheCocoLabelsInUltralyticsTerms) {
  const LabelRun run = run_labels("labels_yolo", {"coco:coco", "yolo:yolo"}, 5);
  ASSERT_EQ(run.seen.size(), 5u);
  const fs::path coco_dir = fs::path(run.dir) / "coco", yolo = fs::path(run.dir) / "yolo";
  EXPECT_FALSE(fs::exists(yolo / "INCOMPLETE"));
  // dataset.yaml: 10 keypoints of 3 numbers; the flip pairs swap left and right.
  std::ifstream yin(yolo / "dataset.yaml");
  std::stringstream ys;
  ys << yin.rdbuf();
  const std::string yaml = ys.str();
  EXPECT_NE(yaml.find("kpt_shape: [10, 3]"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("flip_idx: [0, 1, 3, 2, 4, 6, 5, 8, 7, 9]"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("path: " + fs::absolute(yolo).string()), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("0: receiver"), std::string::npos);
  EXPECT_NE(yaml.find("1: boom"), std::string::npos);
  const json coco = read_json(coco_dir / "annotations.json");
  std::map<std::int64_t, std::vector<json>> by_image;
  for (const json& a : coco["annotations"]) by_image[a["image_id"].get<std::int64_t>()].push_back(a);
  int lines_seen = 0;
  for (const json& image : coco["images"]) {
    const std::string file = image["file_name"].get<std::string>();
    EXPECT_TRUE(fs::exists(yolo / file)) << file;
    const std::string stem = fs::path(file).stem().string();
    std::ifstream in(yolo / "labels" / (stem + ".txt"));
    ASSERT_TRUE(in) << stem;
    const double w = image["width"].get<double>(), h = image["height"].get<double>();
    std::vector<json> anns = by_image[image["id"].get<std::int64_t>()];
    std::size_t next = 0;
    for (std::string line; std::getline(in, line); ++next) {
      std::istringstream s(line);
      std::vector<double> v;
      for (double x; s >> x;) v.push_back(x);
      ASSERT_EQ(v.size(), 5u + 3 * 10) << "every line has all keypoints: " << line;
      ASSERT_LT(next, anns.size());
      const json& a = anns[next];
      EXPECT_EQ(static_cast<int>(v[0]), a["category_id"].get<int>() - 1);
      const auto bb = a["bbox"].get<std::vector<double>>();
      EXPECT_NEAR(v[1], (bb[0] + bb[2] / 2) / w, 1e-6);
      EXPECT_NEAR(v[2], (bb[1] + bb[3] / 2) / h, 1e-6);
      EXPECT_NEAR(v[3], bb[2] / w, 1e-6);
      EXPECT_NEAR(v[4], bb[3] / h, 1e-6);
      for (int k = 0; k < 10; ++k) {
        const double* kp = &v[5 + 3 * k];
        if (v[0] == 1) {
          EXPECT_EQ(kp[0] + kp[1] + kp[2], 0.0);
          continue;
        }
        const int flag = a["keypoints"][3 * k + 2].get<int>();
        EXPECT_EQ(static_cast<int>(kp[2]), flag);
        if (!flag) continue;
        // YOLO's continuous, normalised coordinates: COCO's pixel index + 0.5, over the size.
        EXPECT_NEAR(kp[0], (a["keypoints"][3 * k].get<double>() + 0.5) / w, 2e-5);
        EXPECT_NEAR(kp[1], (a["keypoints"][3 * k + 1].get<double>() + 0.5) / h, 2e-5);
        EXPECT_TRUE(kp[0] > 0 && kp[0] < 1 && kp[1] > 0 && kp[1] < 1);
      }
      ++lines_seen;
    }
    EXPECT_EQ(next, anns.size()) << stem;
  }
  EXPECT_GT(lines_seen, 10);
}

TEST(LabelsSink, TheRigsOwnKeypointsAndTheirFlipPairs) {
  Rig rig = Rig::paper_default();
  rig.receiver.keypoints = {{"nose", {6.0, 0, 0}},
                            {"left_wing", {0, -8.0, 0}},
                            {"right_wing", {0, 8.0, 0}},
                            {"receptacle", rig.receiver.receptacle_m}};
  const LabelRun run = run_labels("labels_own", {"coco:coco", "yolo:yolo"}, 1, &rig);
  const json coco = read_json(fs::path(run.dir) / "coco" / "annotations.json");
  EXPECT_EQ(coco["categories"][0]["keypoints"], json({"nose", "left_wing", "right_wing", "receptacle"}));
  std::ifstream yin(fs::path(run.dir) / "yolo" / "dataset.yaml");
  std::stringstream ys;
  ys << yin.rdbuf();
  EXPECT_NE(ys.str().find("kpt_shape: [4, 3]"), std::string::npos) << ys.str();
  EXPECT_NE(ys.str().find("flip_idx: [0, 2, 1, 3]"), std::string::npos) << ys.str();
  for (const json& a : coco["annotations"]) {
    if (a["category_id"] == 1) {
      EXPECT_EQ(a["keypoints"].size(), 12u);
    }
  }
}

TEST(LabelsSink, BadArgumentsAndUsedFoldersAreRefused) {
  const std::string dir = test::output_dir("labels_bad");
  const Rig rig = Rig::paper_default();
  auto bad = make_sink("coco:" + dir + "/a,png", {rig});
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("unknown option 'png', expected coco:DIR[,jpeg]"), std::string::npos)
      << bad.error().message;
  std::ofstream(dir + "/annotations.json") << "{}";
  auto used = make_sink("coco:" + dir, {rig});
  ASSERT_FALSE(used);
  EXPECT_NE(used.error().message.find("holds labels already (annotations.json)"), std::string::npos)
      << used.error().message;
  Rig capture_only = rig;
  capture_only.boom.configured = false;
  auto no_boom = make_sink("yolo:" + dir + "/b", {capture_only});
  ASSERT_FALSE(no_boom);
  EXPECT_NE(no_boom.error().message.find("a capture-only rig"), std::string::npos) << no_boom.error().message;
  Rig missing = rig;
  missing.receiver.model.path = dir + "/no_such_receiver.glb";
  auto no_model = make_sink("yolo:" + dir + "/c", {missing});
  ASSERT_FALSE(no_model);
  EXPECT_NE(no_model.error().message.find("receiver model:"), std::string::npos) << no_model.error().message;
}

TEST(LabelsSink, ARunWithoutTheReceiverStopsWithAClearError) {
  const std::string dir = test::output_dir("labels_no_receiver");
  PipelineParts p = test::pipeline_parts(kScenario);
  p.max_pairs = 2;
  p.augment.receiver_proxy = false;
  p.augment.stereo_classes = false;
  auto sink = make_sink("coco:" + dir + "/coco", {p.rig});
  ASSERT_TRUE(sink) << sink.error().message;
  p.sinks.push_back(std::move(*sink));
  Pipeline pipeline(std::move(p));
  std::ostringstream o, e;
  auto report = pipeline.run(o, e);
  ASSERT_FALSE(report);
  EXPECT_NE(report.error().message.find("the receiver was not rendered (--no-receiver?): keypoint labels need its mask and depth"), std::string::npos) << report.error().message;
  EXPECT_TRUE(fs::exists(fs::path(dir) / "coco" / "INCOMPLETE"));
}

TEST(LabelsSink, JpegImagesOnRequest) {
  const LabelRun run = run_labels("labels_jpeg", {"yolo:yolo,jpeg"}, 1);
  const fs::path yolo = fs::path(run.dir) / "yolo";
  EXPECT_TRUE(fs::exists(yolo / "images" / "000000_left.jpg"));
  EXPECT_TRUE(fs::exists(yolo / "labels" / "000000_left.txt"));
  const cv::Mat im = cv::imread((yolo / "images" / "000000_right.jpg").string());
  EXPECT_EQ(im.cols, run.rig.right().model.width_px);
}

}  // namespace
}  // namespace augrig::pipeline
