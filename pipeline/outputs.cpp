#include "pipeline/outputs.hpp"

#include <array>
#include <cstring>


#include "render/ground_truth.hpp"
#include "render/image_file.hpp"
#include "render/visualize.hpp"

namespace augrig::pipeline {

namespace fs = std::filesystem;

namespace {
Status write_png(const fs::path& path, const Image& image) {
  std::error_code ec;
  fs::create_directories(path.parent_path(), ec);
  if (ec) return make_error(path.parent_path().string(), ": cannot create the folder (", ec.message(), ")");
  return write_png_file(path.string(), image);
}
}  // namespace

Expected<RigModels> load_rig_models(const Rig& rig) {
  RigModels r;
  if (rig.receiver.model.path.empty()) {
    r.receiver_model = std::make_shared<const Model>(make_builtin_receiver(&r.receptacle_m));
  } else {
    auto m = load_model(rig.receiver.model);
    if (!m) return make_error("receiver model: ", m.error().message);
    r.receiver_model = std::make_shared<const Model>(std::move(*m));
    r.receptacle_m = rig.receiver.receptacle_m;
  }
  if (!rig.boom.model.path.empty()) {
    auto m = load_model(rig.boom.model);
    if (!m) return make_error("boom model: ", m.error().message);
    auto boom = std::make_shared<BoomModel>();
    boom->fixed = std::move(*m);  // a user boom is one rigid part (no telescope), as the Augmenter has it
    r.boom_model = std::move(boom);
  }
  return r;
}

Eigen::Vector3d receptacle_of(const Rig& rig) {
  if (!rig.receiver.model.path.empty()) return rig.receiver.receptacle_m;
  Eigen::Vector3d receptacle_m;
  (void)make_builtin_receiver(&receptacle_m);
  return receptacle_m;
}

Status write_frame_images(const fs::path& out, const FrameNames& n, const StereoFrame& raw, const StereoResult& r) {
  const std::string l = n.left + ".png", rr = n.right + ".png";
  const std::pair<fs::path, Image> files[] = {
      {out / "left" / "augmented" / l, whole_augmented(raw.left.image, r.left)},
      {out / "right" / "augmented" / rr, whole_augmented(raw.right.image, r.right)},
      {out / "left" / "mask" / l, r.left.mask},
      {out / "right" / "mask" / rr, r.right.mask},
      {out / "vis" / "boom_overlap" / l, visualize_boom_overlap(r.left.mask, r.right.mask)},
      {out / "vis" / "occlusion_left" / l, visualize_receiver_occlusion(r.left.mask, true)},
      {out / "vis" / "occlusion_right" / rr, visualize_receiver_occlusion(r.right.mask, false)},
  };
  for (const auto& [path, image] : files)
    if (Status s = write_png(path, image); !s) return s;
  if (!r.stereo_classes.empty())
    return write_png(
        out / "vis" / "stereo_classes" / l,
        visualize_stereo_classes(r.stereo_classes, r.left.mask.width(), r.left.mask.height()));
  return {};
}

Status write_ground_truth(const fs::path& out, const FrameNames& n, const StereoResult& r, const Rig& rig) {
  const std::array<const ViewResult*, 2> views = {&r.left, &r.right};
  const std::array<const std::string*, 2> stems = {&n.left, &n.right};
  for (int c = 0; c < 2; ++c) {
    const DepthImage& d = views[c]->receiver_depth;
    if (d.width <= 0 || d.height <= 0)
      return make_error("ground truth: the ", c ? "right" : "left", " view has no depth image");
    const fs::path side = out / (c ? "right" : "left");
    for (const char* sub : {"depth", "depth_mm"}) {
      std::error_code ec;
      fs::create_directories(side / sub, ec);
      if (ec) return make_error((side / sub).string(), ": cannot create the folder (", ec.message(), ")");
    }
    if (Status s = write_depth_npy((side / "depth" / (*stems[c] + ".npy")).string(), d); !s) return s;
    if (Status s = write_depth_mm_png((side / "depth_mm" / (*stems[c] + ".png")).string(), d); !s) return s;
  }
  // Where each left receiver point lies in the right image: the true correspondence.
  const fs::path left = out / "left";
  for (const char* sub : {"right_px", "stereo_class"}) {
    std::error_code ec;
    fs::create_directories(left / sub, ec);
    if (ec) return make_error((left / sub).string(), ": cannot create the folder (", ec.message(), ")");
  }
  const std::vector<float> uv =
      right_correspondence(r.left.receiver_depth, rig.left().model, rig.right().model, rig.T_right_left());
  const int w = r.left.receiver_depth.width, h = r.left.receiver_depth.height;
  if (Status s = write_correspondence_npy((left / "right_px" / (n.left + ".npy")).string(), uv, w, h); !s) return s;
  if (r.stereo_classes.size() == static_cast<std::size_t>(w) * static_cast<std::size_t>(h))
    return write_stereo_class_png((left / "stereo_class" / (n.left + ".png")).string(), r.stereo_classes, w, h);
  return {};
}

recorder::FrameRecord frame_record(const StereoResult& r, bool ground_truth) {
  recorder::FrameRecord fr;
  fr.augmented = {r.left.augmented, r.right.augmented};
  // The changed-box output made only the boxes (an image of the box's size).
  for (const ViewResult* v : {&r.left, &r.right})
    if (v->augmented.width() == v->augmented_box.width() && v->augmented.height() == v->augmented_box.height())
      fr.augmented_box[v == &r.left ? 0 : 1] = v->augmented_box;
  fr.mask = {r.left.mask, r.right.mask};
  fr.stats = r.stats;
  // The correspondence and the stereo classes follow from the depth, the masks and the rig, so the
  // depth is all a recording needs to give the whole ground truth back (recorder/euroc.hpp).
  if (ground_truth)
    fr.receiver_depth = {recorder::DepthRecord::from(r.left.receiver_depth),
                         recorder::DepthRecord::from(r.right.receiver_depth)};
  return fr;
}

Expected<std::unique_ptr<StatsCsvWriter>> StatsCsvWriter::create(const fs::path& path) {
  std::unique_ptr<StatsCsvWriter> w(new StatsCsvWriter);
  w->path_ = path;
  w->out_.open(path, std::ios::binary);
  if (!w->out_) return make_error(path.string(), ": cannot write the statistics file");
  write_stats_csv_header(w->out_);
  return w;
}

Status StatsCsvWriter::add(const OcclusionStats& s) {
  write_stats_csv_row(out_, s);
  out_.flush();
  if (!out_) return make_error(path_.string(), ": write failed");
  return {};
}

}  // namespace augrig::pipeline
