// Labels for learned pose estimation as sinks (`--sink coco:DIR`, `--sink yolo:DIR`; `augrig export IN
// OUT --format coco|yolo`; docs/LABELS.md): each camera's augmented image of each pair, with the
// receiver's keypoints (render/keypoints.hpp: where each lies and whether the boom, the receiver
// itself or nothing hides it), and the receiver's and the boom's boxes and instance masks:
//   coco: DIR/images/NNNNNN_CAM.png, DIR/annotations.json: COCO's keypoint format, one image per
//         camera and pair, one annotation per object seen (receiver: category 1, with keypoints
//         x,y,v, v = 0 not labelled, 1 hidden, 2 visible; boom: category 2), masks as COCO's
//         uncompressed RLE (column-major runs from a 0 run); our finer keypoint classes, every
//         keypoint's projection and the receiver's amodal mask (boom-hidden pixels included) in
//         fields named augrig_*;
//   yolo: DIR/images/NNNNNN_CAM.png, DIR/labels/NNNNNN_CAM.txt (Ultralytics' pose format: "class cx cy
//         w h" then x y v per keypoint, normalised; the boom, class 1, with its keypoints all 0),
//         DIR/dataset.yaml (kpt_shape, flip_idx, names).
// Both: DIR/keypoints.csv, every keypoint in every image with its finer class and the pixel that
// decided it. The masks are the augmenter's own (kMaskReceiver without kMaskBoom: the receiver's
// visible pixels), so a label never disagrees with them. Coordinates: COCO's keypoints are pixel
// indices (centres at integers, as ours), its boxes and YOLO's numbers continuous (a pixel spans
// [i, i+1)). Pairs without an augmentation are left out and counted. DIR/INCOMPLETE stays until
// the run closes the sink cleanly.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "core/conventions.hpp"
#include "pipeline/outputs.hpp"
#include "pipeline/report.hpp"
#include "pipeline/sinks/registry.hpp"
#include "pipeline/sinks/sink_folder.hpp"
#include "render/cv_image.hpp"
#include "render/keypoints.hpp"

namespace augrig::pipeline {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

enum class Format { kCoco, kYolo };

const char* name_of(Format f) {
  return f == Format::kCoco ? "coco" : "yolo";
}

// One object's pixels in one image: its box ([x0, x1) x [y0, y1)), its area and its runs.
struct Instance {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  std::int64_t area = 0;
  std::vector<std::uint32_t> counts;  // COCO's uncompressed RLE: column-major, from a run of 0s
  bool empty() const { return area == 0; }
};

// One camera's labels of one pair.
struct ViewLabels {
  bool receiver_in_scene = false;
  std::vector<KeypointInView> keypoints;                  // with the receiver in the scene
  std::vector<std::optional<Eigen::Vector2d>> projected;  // each keypoint's projection, in or off the image
  Instance receiver, receiver_amodal, boom;
};

// The three instances of a mask in one column-major pass: the receiver's visible pixels (receiver
// bit without the boom's), all its pixels (amodal) and the boom's.
void find_instances(ConstImageView mask, ViewLabels& v) {
  Instance* inst[3] = {&v.receiver, &v.receiver_amodal, &v.boom};
  bool on[3] = {false, false, false};
  std::uint32_t run[3] = {0, 0, 0};
  for (Instance* i : inst) i->x0 = mask.width, i->y0 = mask.height;
  for (int x = 0; x < mask.width; ++x)
    for (int y = 0; y < mask.height; ++y) {
      const std::uint8_t m = mask.row(y)[x];
      const bool now[3] = {(m & kMaskReceiver) && !(m & kMaskBoom), (m & kMaskReceiver) != 0,
                           (m & kMaskBoom) != 0};
      for (int k = 0; k < 3; ++k) {
        if (now[k] != on[k]) {
          inst[k]->counts.push_back(run[k]);
          run[k] = 0;
          on[k] = now[k];
        }
        ++run[k];
        if (now[k]) {
          Instance& i = *inst[k];
          ++i.area;
          i.x0 = std::min(i.x0, x), i.y0 = std::min(i.y0, y);
          i.x1 = std::max(i.x1, x + 1), i.y1 = std::max(i.y1, y + 1);
        }
      }
    }
  for (int k = 0; k < 3; ++k) {
    inst[k]->counts.push_back(run[k]);
    if (inst[k]->empty()) inst[k]->x0 = inst[k]->y0 = 0;
  }
}

json rle(const Instance& i, int width, int height) {
  return {{"size", {height, width}}, {"counts", i.counts}};
}

json box(const Instance& i) {
  return {i.x0, i.y0, i.x1 - i.x0, i.y1 - i.y0};
}

// Two decimals: a hundredth of a pixel, well below any label's accuracy.
double round2(double v) {
  return std::round(v * 100.0) / 100.0;
}

std::string fixed(double v, int digits) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

class LabelsSink final : public FrameSink {
 public:
  LabelsSink(Format format, std::string dir, bool jpeg, const Rig& rig)
      : format_(format),
        dir_(std::move(dir)),
        out_(std::string(name_of(format)) + " sink", dir_),
        jpeg_(jpeg),
        rig_(rig) {}

  Status open() {
    const std::string where = std::string(name_of(format_)) + " sink: " + dir_;
    if (rig_.cameras.size() != 2) return make_error(where, ": the rig needs 2 cameras");
    if (!rig_.boom.configured) return make_error(where, ": ", rig_.source, ": a capture-only rig (no boom)");
    // The receiver as the augmenter draws it (the built-in one with its own receptacle).
    auto models = load_rig_models(rig_);
    if (!models) return make_error(where, ": ", models.error().message);
    ReceiverConfig receiver = rig_.receiver;
    receiver.receptacle_m = models->receptacle_m;
    keypoints_ = receiver_keypoints(receiver, *models->receiver_model);
    std::error_code ec;
    for (const char* f : {"annotations.json", "dataset.yaml", "keypoints.csv"})
      if (fs::exists(fs::path(dir_) / f, ec))
        return make_error(where, ": holds labels already (", f, "); expected a new folder");
    const std::vector<std::string> subfolders = format_ == Format::kYolo
                                                    ? std::vector<std::string>{"images", "labels"}
                                                    : std::vector<std::string>{"images"};
    if (Status s = out_.create(subfolders, "removed when the labels are complete"); !s) return s;
    csv_.open(fs::path(dir_) / "keypoints.csv", std::ios::binary);
    csv_
        << "# every receiver keypoint in every image; u_px, v_px: its projection (pixel centres at integers; "
           "empty: behind the camera); class: outside, visible, hidden_by_boom, hidden_by_receiver or "
           "not_drawn; decided_x, decided_y: the pixel that decided it (-1: outside); coco_v: COCO's flag\n"
           "image,camera,t_ns,keypoint,u_px,v_px,class,decided_x,decided_y,coco_v\n";
    if (!csv_) return make_error(where, "/keypoints.csv: cannot write the file");
    return {};
  }

  SinkNeeds needs() const override { return {.whole_images = true}; }

  Status consume(PairContext& pair) override {
    Status s = label_pair(pair);
    failed_ = failed_ || !s;
    return s;
  }

  Status close(PipelineReport& report) override {
    if (!csv_.is_open() || failed_) return {};  // a failed run's folder stays INCOMPLETE
    csv_.close();
    if (!csv_) return make_error(name_of(format_), " sink: ", dir_, "/keypoints.csv: write failed");
    if (Status s = format_ == Format::kCoco ? write_coco() : write_dataset_yaml(); !s) return s;
    out_.complete();
    std::ostringstream line;
    line << dir_ << ": " << 2 * pairs_ << " image(s) of " << pairs_ << " pair(s) labelled in "
         << (format_ == Format::kCoco ? "COCO's keypoint format" : "YOLO's pose format") << " ("
         << keypoints_.size() << " keypoints: " << visible_ << " visible, " << hidden_by_boom_
         << " hidden by the boom, " << hidden_by_receiver_ << " by the receiver, " << unlabelled_
         << " outside or not drawn; " << receivers_ << " receiver and " << booms_ << " boom instance(s))";
    if (left_out_) line << "; " << left_out_ << " pair(s) without an augmentation left out";
    report.outputs.push_back(line.str());
    return {};
  }

 private:
  // One pair: each camera's image, keypoints and instances.
  Status label_pair(PairContext& pair) {
    if (!pair.result || !pair.scene) {
      ++left_out_;
      return {};
    }
    pair.make_whole();
    char id[32];
    std::snprintf(id, sizeof id, "%06zu", pairs_);
    for (int c = 0; c < 2; ++c) {
      const RigCamera& cam = rig_.cameras[static_cast<std::size_t>(c)];
      const ViewResult& view = c ? pair.result->right : pair.result->left;
      const Frame& raw = c ? pair.raw.right : pair.raw.left;
      auto labels = label_view(cam, view, *pair.scene, pair.result->receiver_drawn);
      if (!labels) return make_error(name_of(format_), " sink: ", dir_, ": ", labels.error().message);
      const std::string stem = std::string(id) + "_" + (c ? "right" : "left");
      const std::string image = "images/" + stem + (jpeg_ ? ".jpg" : ".png");
      if (Status s = write_image(image, view.augmented); !s) return s;
      const Record r{image, stem, cam.name, c, raw.t_ns, pair};
      if (Status s = write_csv(r, *labels); !s) return s;
      if (Status s =
              format_ == Format::kCoco ? add_coco(r, *labels, cam.model) : write_yolo(r, *labels, cam.model);
          !s)
        return s;
    }
    ++pairs_;
    return {};
  }

  // What one image's rows share.
  struct Record {
    std::string image, stem, camera;
    int camera_index = 0;
    TimestampNs t_ns = 0;
    const PairContext& pair;
  };

  Expected<ViewLabels> label_view(const RigCamera& cam, const ViewResult& view, const SceneState& scene,
                                  bool receiver_drawn) {
    const int w = cam.model.width_px, h = cam.model.height_px;
    if (view.mask.width() != w || view.mask.height() != h || view.augmented.width() != w ||
        view.augmented.height() != h)
      return make_error("camera ", cam.name, ": an image is ", view.mask.width(), "x", view.mask.height(),
                        ", the rig's camera ", w, "x", h);
    ViewLabels v;
    v.receiver_in_scene = scene.receiver_present;
    find_instances(view.mask.cview(), v);
    if (!v.receiver_in_scene) return v;
    if (!receiver_drawn || view.receiver_depth.width != w || view.receiver_depth.height != h)
      return make_error("the receiver was not rendered (--no-receiver?): keypoint labels need its mask and depth");
    const Pose T_cam_receiver = cam.T_body_cam.inverse() * scene.T_body_receiver;
    for (const Keypoint& k : keypoints_) {
      const Eigen::Vector3d p_cam_m = T_cam_receiver * k.p_receiver_m;
      v.projected.push_back(cam.model.project(p_cam_m));
      v.keypoints.push_back(locate_keypoint(p_cam_m, cam.model, view.mask.cview(), view.receiver_depth));
      switch (v.keypoints.back().cls) {
        case KeypointClass::kVisible:
          ++visible_;
          break;
        case KeypointClass::kHiddenByBoom:
          ++hidden_by_boom_;
          break;
        case KeypointClass::kHiddenByReceiver:
          ++hidden_by_receiver_;
          break;
        default:
          ++unlabelled_;
      }
    }
    receivers_ += !v.receiver.empty();
    booms_ += !v.boom.empty();
    return v;
  }

  Status write_csv(const Record& r, const ViewLabels& v) {
    for (std::size_t k = 0; k < v.keypoints.size(); ++k) {
      const KeypointInView& p = v.keypoints[k];
      const std::optional<Eigen::Vector2d>& uv = v.projected[k];
      csv_ << r.image << "," << r.camera << "," << r.t_ns << "," << keypoints_[k].name << ","
           << (uv ? fixed(uv->x(), 3) : "") << "," << (uv ? fixed(uv->y(), 3) : "") << "," << to_string(p.cls)
           << "," << p.decided_x << "," << p.decided_y << "," << coco_visibility(p.cls) << "\n";
    }
    if (!csv_) return make_error(name_of(format_), " sink: ", dir_, "/keypoints.csv: write failed");
    return {};
  }

  // COCO: the image and its annotations, kept as JSON text until the close.
  Status add_coco(const Record& r, const ViewLabels& v, const CameraModel& cam) {
    const int w = cam.width_px, h = cam.height_px;
    const std::int64_t image_id = static_cast<std::int64_t>(images_.size()) + 1;
    images_.push_back(
        json{{"id", image_id},
             {"file_name", r.image},
             {"width", w},
             {"height", h},
             {"augrig_camera", r.camera},
             {"augrig_t_ns", r.t_ns},
             {"augrig_pair", pairs_},
             {"augrig_source_index",
              r.pair.position ? static_cast<std::uint64_t>(r.pair.position->index) : r.pair.pair - 1}}
            .dump());
    if (v.receiver_in_scene && !v.receiver.empty()) {
      json kp = json::array(), cls = json::array(), projected = json::array();
      int labelled = 0;
      for (std::size_t k = 0; k < v.keypoints.size(); ++k) {
        const KeypointInView& p = v.keypoints[k];
        const int flag = coco_visibility(p.cls);
        labelled += flag > 0;
        kp.push_back(flag ? round2(p.uv_px.x()) : 0.0);
        kp.push_back(flag ? round2(p.uv_px.y()) : 0.0);
        kp.push_back(flag);
        cls.push_back(std::string(to_string(p.cls)));
        const std::optional<Eigen::Vector2d>& uv = v.projected[k];
        projected.push_back(uv ? json{round2(uv->x()), round2(uv->y())} : json(nullptr));
      }
      annotations_.push_back(json{{"id", ++annotation_id_},
                                  {"image_id", image_id},
                                  {"category_id", 1},
                                  {"iscrowd", 0},
                                  {"bbox", box(v.receiver)},
                                  {"area", v.receiver.area},
                                  {"segmentation", rle(v.receiver, w, h)},
                                  {"keypoints", kp},
                                  {"num_keypoints", labelled},
                                  {"augrig_keypoint_classes", cls},
                                  {"augrig_keypoints_projected", projected},
                                  {"augrig_amodal_bbox", box(v.receiver_amodal)},
                                  {"augrig_amodal_area", v.receiver_amodal.area},
                                  {"augrig_amodal_segmentation", rle(v.receiver_amodal, w, h)}}
                                 .dump());
    }
    if (!v.boom.empty())
      annotations_.push_back(json{
          {"id", ++annotation_id_},
          {"image_id", image_id},
          {"category_id", 2},
          {"iscrowd", 0},
          {"bbox", box(v.boom)},
          {"area", v.boom.area},
          {"segmentation",
           rle(v.boom, w, h)}}.dump());
    return {};
  }

  // The skeleton between the default names that are there (COCO's pairs count from 1).
  json skeleton() const {
    static const char* kEdges[][2] = {{"nose", "receptacle"},
                                      {"nose", "wing_tip_left"},
                                      {"nose", "wing_tip_right"},
                                      {"wing_tip_left", "tail"},
                                      {"wing_tip_right", "tail"},
                                      {"tail", "fin_tip"},
                                      {"tail", "tailplane_tip_left"},
                                      {"tail", "tailplane_tip_right"},
                                      {"nacelle_front_left", "wing_tip_left"},
                                      {"nacelle_front_right", "wing_tip_right"}};
    auto index = [&](const char* n) {
      for (std::size_t i = 0; i < keypoints_.size(); ++i)
        if (keypoints_[i].name == n) return static_cast<int>(i) + 1;
      return 0;
    };
    json s = json::array();
    for (const auto& e : kEdges)
      if (index(e[0]) && index(e[1])) s.push_back({index(e[0]), index(e[1])});
    return s;
  }

  Status write_coco() const {
    json names = json::array();
    for (const Keypoint& k : keypoints_) names.push_back(k.name);
    const json head{{"description", "augrig: receiver keypoints and boom occlusion (docs/LABELS.md)"},
                    {"version", "1.0"},
                    {"augrig_rig", rig_.source}};
    const json categories = json::array({json{{"id", 1},
                                              {"name", "receiver"},
                                              {"supercategory", "aircraft"},
                                              {"keypoints", names},
                                              {"skeleton", skeleton()}},
                                         json{{"id", 2}, {"name", "boom"}, {"supercategory", "aircraft"}}});
    // Written whole into a temporary file, then renamed: a reader never sees half of it.
    const fs::path path = fs::path(dir_) / "annotations.json", tmp = fs::path(dir_) / "annotations.json.tmp";
    std::ofstream out(tmp, std::ios::binary);
    out << "{\"info\": " << head.dump() << ",\n\"licenses\": [],\n\"categories\": " << categories.dump()
        << ",\n\"images\": [";
    for (std::size_t i = 0; i < images_.size(); ++i) out << (i ? ",\n" : "\n") << images_[i];
    out << "],\n\"annotations\": [";
    for (std::size_t i = 0; i < annotations_.size(); ++i) out << (i ? ",\n" : "\n") << annotations_[i];
    out << "]}\n";
    out.close();
    std::error_code ec;
    if (out) fs::rename(tmp, path, ec);
    if (!out || ec) return make_error("coco sink: ", path.string(), ": cannot write the file");
    return {};
  }

  // YOLO: one line per object seen, the receiver's with its keypoints, the boom's with zeros.
  Status write_yolo(const Record& r, const ViewLabels& v, const CameraModel& cam) const {
    const double w = cam.width_px, h = cam.height_px;
    std::ostringstream o;
    auto box_of = [&](int cls, const Instance& i) {
      o << cls << " " << fixed((i.x0 + i.x1) / 2.0 / w, 6) << " " << fixed((i.y0 + i.y1) / 2.0 / h, 6) << " "
        << fixed((i.x1 - i.x0) / w, 6) << " " << fixed((i.y1 - i.y0) / h, 6);
    };
    if (v.receiver_in_scene && !v.receiver.empty()) {
      box_of(0, v.receiver);
      for (const KeypointInView& p : v.keypoints) {
        const int flag = coco_visibility(p.cls);
        o << " " << (flag ? fixed((p.uv_px.x() + 0.5) / w, 6) : "0") << " "
          << (flag ? fixed((p.uv_px.y() + 0.5) / h, 6) : "0") << " " << flag;
      }
      o << "\n";
    }
    if (!v.boom.empty()) {
      box_of(1, v.boom);
      for (std::size_t k = 0; k < keypoints_.size(); ++k) o << " 0 0 0";
      o << "\n";
    }
    return out_.write_text("labels/" + r.stem + ".txt", o.str());
  }

  Status write_dataset_yaml() const {
    std::ostringstream y;
    y << "# augrig: receiver keypoints and boom occlusion in Ultralytics' pose format (docs/LABELS.md)\n"
      << "path: " << fs::absolute(dir_).string() << "\ntrain: images\nval: images\n"
      << "kpt_shape: [" << keypoints_.size() << ", 3]\nflip_idx: [";
    const std::vector<int> flip = keypoint_flip_index(keypoints_);
    for (std::size_t i = 0; i < flip.size(); ++i) y << (i ? ", " : "") << flip[i];
    y << "]\nnames:\n  0: receiver\n  1: boom\naugrig_keypoints: [";
    for (std::size_t i = 0; i < keypoints_.size(); ++i) y << (i ? ", " : "") << keypoints_[i].name;
    y << "]\n";
    return out_.write_text("dataset.yaml", y.str());
  }

  Status write_image(const std::string& rel, const Image& image) const {
    const cv::Mat bgr = bgr_of(image.cview());
    return out_.write_image(rel, bgr,
                            jpeg_ ? std::vector<int>{cv::IMWRITE_JPEG_QUALITY, 95} : std::vector<int>{});
  }

  Format format_;
  std::string dir_;
  SinkFolder out_;  // dir_: made, marked INCOMPLETE until the close, the files written
  bool jpeg_ = false;
  const Rig rig_;  // a copy: the setup's rig moves into the pipeline
  std::vector<Keypoint> keypoints_;
  std::ofstream csv_;
  std::vector<std::string> images_, annotations_;  // COCO's entries, as JSON
  std::int64_t annotation_id_ = 0;
  std::size_t pairs_ = 0, left_out_ = 0;
  bool failed_ = false;  // a pair could not be labelled: the run stops, the folder stays INCOMPLETE
  std::int64_t visible_ = 0, hidden_by_boom_ = 0, hidden_by_receiver_ = 0, unlabelled_ = 0;
  std::int64_t receivers_ = 0, booms_ = 0;
};

Expected<std::unique_ptr<FrameSink>> make(Format format, const std::string& arg, const SinkSetup& setup) {
  std::string dir = arg;
  bool jpeg = false;
  if (const std::size_t comma = arg.find(','); comma != std::string::npos) {
    dir = arg.substr(0, comma);
    if (arg.substr(comma + 1) != "jpeg")
      return make_error("--sink ", name_of(format), ":", arg, ": unknown option '", arg.substr(comma + 1),
                        "', expected ", name_of(format), ":DIR[,jpeg]");
    jpeg = true;
  }
  auto sink = std::make_unique<LabelsSink>(format, dir, jpeg, setup.rig);
  if (Status s = sink->open(); !s) return s.error();
  return std::unique_ptr<FrameSink>(std::move(sink));
}

}  // namespace

Expected<std::unique_ptr<FrameSink>> make_coco_sink(const std::string& arg, const SinkSetup& setup) {
  return make(Format::kCoco, arg, setup);
}

Expected<std::unique_ptr<FrameSink>> make_yolo_sink(const std::string& arg, const SinkSetup& setup) {
  return make(Format::kYolo, arg, setup);
}

}  // namespace augrig::pipeline
