// The augrig commands. Flow of every command: parse the flags (usage errors exit 2), load and
// check every input file before the GL context exists (content errors exit 1 with file and line),
// then create the EGL headless context and the Augmenter and process frame by frame.
#include "app/commands.hpp"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "app/scene_file.hpp"
#include "capture/stereo_pairer.hpp"
#include "core/frame.hpp"
#include "render/augmenter.hpp"
#include "render/gl_context.hpp"
#include "render/models.hpp"
#include "render/rig.hpp"
#include "render/stats.hpp"
#include "render/visualize.hpp"
#include "sim/approach.hpp"

#ifndef AUGRIG_VERSION
#define AUGRIG_VERSION "unknown"
#endif

namespace augrig::app {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// A command failed for a reason the user can fix in an input (exit 1) or in the flags (exit 2).
struct CommandError {
  int code;
  std::string message;
};
[[noreturn]] void runtime_error(const std::string& what) {
  throw CommandError{kExitRuntime, what};
}
[[noreturn]] void usage_error(const std::string& what) {
  throw CommandError{kExitUsage, what};
}

// Library errors read "module::function(): file:line: ..."; the CLI prints its own prefix instead,
// so the user sees "augrig augment: file:line: ...".
std::string user_message(const Error& e) {
  const std::string& m = e.message;
  const auto end = m.find("(): ");
  if (end != std::string::npos && end < 48) {
    const std::string head = m.substr(0, end);
    if (head.find("::") != std::string::npos && head.find(' ') == std::string::npos) return m.substr(end + 4);
  }
  return m;
}

template <typename T>
T unwrap(Expected<T> e) {
  if (!e) runtime_error(user_message(e.error()));
  return std::move(e).value();
}
void check(const Status& s) {
  if (!s) runtime_error(user_message(s.error()));
}

// ---- Shared flag handling -----------------------------------------------------------------------

// "default" is the seed paper's rig; anything else a rig file.
Rig load_rig_arg(const std::string& value) {
  if (value.empty() || value == "default") return Rig::paper_default();
  return unwrap(load_rig(value));
}

ReceiverDraw parse_receiver_draw(const std::string& v) {
  if (v.empty() || v == "mask") return ReceiverDraw::kMaskOnly;
  if (v == "wireframe") return ReceiverDraw::kWireframe;
  if (v == "translucent") return ReceiverDraw::kTranslucent;
  usage_error("--receiver-draw: expected one of mask, wireframe, translucent, got '" + v + "'");
}

PixelFormat parse_bayer(const std::string& v) {
  if (v == "RG") return PixelFormat::kBayerRG8;
  if (v == "GR") return PixelFormat::kBayerGR8;
  if (v == "GB") return PixelFormat::kBayerGB8;
  if (v == "BG") return PixelFormat::kBayerBG8;
  usage_error("--bayer: expected one of RG, GR, GB, BG (colour of the top-left 2x2 cell), got '" + v + "'");
}

// The receiver model and where its receptacle is: the built-in model knows its own receptacle;
// a model file relies on the rig's receiver.receptacle_m.
struct ReceiverSetup {
  std::shared_ptr<const Model> model;  // null: let the Augmenter load the rig's file
  Eigen::Vector3d receptacle_m = Eigen::Vector3d::Zero();
};
ReceiverSetup receiver_setup(const Rig& rig) {
  ReceiverSetup r;
  if (rig.receiver.model.path.empty()) {
    r.model = std::make_shared<const Model>(make_builtin_receiver(&r.receptacle_m));
  } else {
    r.receptacle_m = rig.receiver.receptacle_m;
  }
  return r;
}

std::unique_ptr<GlContext> make_gl_context() {
  auto ctx = create_gl_context(GlBackend::kEglHeadless);
  if (!ctx) runtime_error("cannot create an OpenGL context (EGL headless): " + user_message(ctx.error()));
  return std::move(*ctx);
}

void make_dirs(const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) runtime_error(dir.string() + ": cannot create the folder (" + ec.message() + ")");
}

// ---- Outputs ------------------------------------------------------------------------------------

// Per-frame file names: left/right keep their own stems, the visualisations use the left one.
struct FrameNames {
  std::string left, right;
};

void write_png(const fs::path& path, const Image& image) {
  check(write_image_file(path.string(), image));
}

// Everything `augment` writes for one stereo frame (see docs/CLI.md for the layout).
void write_frame_outputs(const fs::path& out, const FrameNames& n, const StereoResult& r) {
  const std::string l = n.left + ".png", rr = n.right + ".png";
  write_png(out / "left" / "augmented" / l, r.left.augmented);
  write_png(out / "right" / "augmented" / rr, r.right.augmented);
  write_png(out / "left" / "mask" / l, r.left.mask);
  write_png(out / "right" / "mask" / rr, r.right.mask);
  write_png(out / "vis" / "boom_overlap" / l, visualize_boom_overlap(r.left.mask, r.right.mask));
  write_png(out / "vis" / "occlusion_left" / l, visualize_receiver_occlusion(r.left.mask, true));
  write_png(out / "vis" / "occlusion_right" / rr, visualize_receiver_occlusion(r.right.mask, false));
  if (!r.stereo_classes.empty()) {
    write_png(out / "vis" / "stereo_classes" / l,
              visualize_stereo_classes(r.stereo_classes, r.left.mask.width(), r.left.mask.height()));
  }
}

// stats.csv, one row per stereo frame, flushed per row so a failed run keeps what it counted.
class StatsCsv {
 public:
  explicit StatsCsv(const fs::path& path) : path_(path), out_(path, std::ios::binary) {
    if (!out_) runtime_error(path.string() + ": cannot write the statistics file");
    write_stats_csv_header(out_);
  }
  void add(const OcclusionStats& s) {
    write_stats_csv_row(out_, s);
    out_.flush();
    if (!out_) runtime_error(path_.string() + ": write failed");
  }

 private:
  fs::path path_;
  std::ofstream out_;
};

// Wall time of one augment() call (its stages overlap across threads, so they are not summed).
double total_ms(const AugmentTimings& t) {
  return t.total_ms;
}

std::string fmt_ms(double ms) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f", ms);
  return buf;
}

// ---- augment ------------------------------------------------------------------------------------

const std::vector<OptionSpec>& augment_specs() {
  static const std::vector<OptionSpec> specs = {
      {"rig", ArgKind::kValue, "RIG.yaml|default",
       "rig file (docs/RIG_FORMAT.md), or 'default' for the paper's rig", true},
      {"scene", ArgKind::kValue, "SCENE.yaml|DIR",
       "boom and receiver pose (docs/CLI.md); a folder holds one scene file per pair (sorted)", true},
      {"left", ArgKind::kValue, "FILE|DIR", "left camera image, or a folder of them (paired by sorted name)",
       true},
      {"right", ArgKind::kValue, "FILE|DIR", "right camera image, or a folder of them", true},
      {"out", ArgKind::kValue, "DIR", "output folder (created)", true},
      {"format", ArgKind::kValue, "png", "output image format (png, lossless)"},
      {"bayer", ArgKind::kValue, "RG|GR|GB|BG", "8-bit gray inputs are raw Bayer mosaics with this pattern"},
      {"no-receiver", ArgKind::kFlag, "",
       "do not render the receiver (no receiver mask bit, no stereo classes)"},
      {"receiver-draw", ArgKind::kValue, "mask|wireframe|translucent",
       "how the receiver shows in the augmented image (default mask: not drawn)"},
  };
  return specs;
}

const char* kAugmentUsage =
    "augrig augment --rig RIG.yaml|default --scene SCENE.yaml --left L --right R --out DIR [options]";
const char* kAugmentSummary =
    "Renders the virtual boom into a stereo pair (or folders of pairs) and writes the augmented images,\n"
    "per-pixel masks (1 boom, 2 receiver, 3 both), visualisations and the occlusion statistics.";

bool is_image_name(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char ch) { return std::tolower(ch); });
  for (const char* e : {".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".pgm", ".ppm", ".pnm"})
    if (ext == e) return true;
  return false;
}

// Regular files of a folder accepted by `keep`, sorted by name.
std::vector<fs::path> list_files(const fs::path& dir, bool (*keep)(const fs::path&)) {
  std::vector<fs::path> files;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    if (entry.is_regular_file() && keep(entry.path())) files.push_back(entry.path());
  }
  if (ec) runtime_error(dir.string() + ": cannot list the folder (" + ec.message() + ")");
  std::sort(files.begin(), files.end(), [](const fs::path& a, const fs::path& b) {
    return a.filename().string() < b.filename().string();
  });
  return files;
}

bool is_scene_name(const fs::path& p) {
  return p.extension() == ".yaml" || p.extension() == ".yml";
}

// The input pairs: two files, or two folders with the same number of images.
std::vector<std::pair<fs::path, fs::path>> input_pairs(const std::string& left, const std::string& right) {
  std::error_code ec;
  const bool ldir = fs::is_directory(left, ec), rdir = fs::is_directory(right, ec);
  if (ldir != rdir) {
    usage_error("--left and --right must both be image files or both folders (--left " + left + " is " +
                (ldir ? "a folder" : "not a folder") + ", --right " + right + " is " +
                (rdir ? "a folder" : "not a folder") + ")");
  }
  if (!ldir) return {{left, right}};
  const auto lf = list_files(left, is_image_name), rf = list_files(right, is_image_name);
  if (lf.size() != rf.size()) {
    runtime_error("the image folders differ in count: " + left + " has " + std::to_string(lf.size()) + ", " +
                  right + " has " + std::to_string(rf.size()) + " image(s); pairs are formed by sorted name");
  }
  if (lf.empty()) runtime_error(left + ": no images (.png .jpg .tif .bmp .pgm .ppm) in the folder");
  std::vector<std::pair<fs::path, fs::path>> pairs;
  for (std::size_t i = 0; i < lf.size(); ++i) pairs.emplace_back(lf[i], rf[i]);
  return pairs;
}

struct SceneInput {
  SceneState scene;
  SceneExtras extras;
};

// One scene for every pair, or a folder with one scene file per pair.
std::vector<SceneInput> load_scenes(const std::string& arg, std::size_t pairs, const Rig& rig,
                                    const Eigen::Vector3d& receptacle_m) {
  std::vector<fs::path> files;
  std::error_code ec;
  if (fs::is_directory(arg, ec)) {
    files = list_files(arg, is_scene_name);
    if (files.size() != pairs) {
      runtime_error(arg + ": has " + std::to_string(files.size()) +
                    " scene file(s) (.yaml), expected one per pair (" + std::to_string(pairs) + ")");
    }
  } else {
    files = {arg};
  }
  std::vector<SceneInput> scenes;
  for (const auto& f : files) {
    SceneInput s;
    s.scene = unwrap(load_scene(f.string(), rig, BoomDimensions{}, receptacle_m, &s.extras));
    scenes.push_back(std::move(s));
  }
  return scenes;
}

// An input image, checked against its camera's resolution.
Image read_camera_image(const fs::path& path, const RigCamera& cam, std::optional<PixelFormat> bayer) {
  Image im = unwrap(read_image_file(path.string(), bayer));
  if (im.width() != cam.model.width_px || im.height() != cam.model.height_px) {
    runtime_error(path.string() + ": image is " + std::to_string(im.width()) + "x" +
                  std::to_string(im.height()) + ", the rig's " + cam.name + " camera is " +
                  std::to_string(cam.model.width_px) + "x" + std::to_string(cam.model.height_px));
  }
  return im;
}

int augment(const std::vector<std::string>& args, std::ostream& out) {
  const ParsedArgs a = [&] {
    auto p = parse_args(args, augment_specs());
    if (!p) usage_error(p.error().message);
    return *p;
  }();
  if (a.help) {
    out << format_help(kAugmentUsage, kAugmentSummary, augment_specs());
    return kExitOk;
  }
  if (a.get("format", "png") != "png") usage_error("--format: expected png, got '" + a.get("format") + "'");
  const std::optional<PixelFormat> bayer =
      a.has("bayer") ? std::optional<PixelFormat>(parse_bayer(a.get("bayer"))) : std::nullopt;
  AugmentOptions options;
  options.receiver_draw = parse_receiver_draw(a.get("receiver-draw"));
  options.receiver_proxy = !a.has("no-receiver");
  options.stereo_classes = options.receiver_proxy;

  // Every input is read and checked before the GL context exists, so bad files fail fast.
  const Rig rig = load_rig_arg(a.get("rig"));
  if (rig.cameras.size() != 2)
    runtime_error(rig.source + ": the rig needs 2 cameras, has " + std::to_string(rig.cameras.size()));
  const auto pairs = input_pairs(a.get("left"), a.get("right"));
  const ReceiverSetup receiver = receiver_setup(rig);
  options.receiver_model = receiver.model;
  const auto scenes = load_scenes(a.get("scene"), pairs.size(), rig, receiver.receptacle_m);
  // The first pair is read up front too: the common mistakes (wrong file, size, depth) show here.
  Image first_left = read_camera_image(pairs[0].first, rig.left(), bayer);
  Image first_right = read_camera_image(pairs[0].second, rig.right(), bayer);

  const fs::path out_dir = a.get("out");
  make_dirs(out_dir);
  StatsCsv csv(out_dir / "stats.csv");

  const auto gl = make_gl_context();
  const auto augmenter = unwrap(Augmenter::create(rig, options));

  StereoResult result;
  std::vector<OcclusionStats> all;
  double augment_ms = 0;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const auto& [lp, rp] = pairs[i];
    const SceneInput& sc = scenes[scenes.size() == 1 ? 0 : i];
    // The timestamp: the scene file's, else the pair's index.
    const TimestampNs t_ns = sc.extras.t_ns.value_or(static_cast<TimestampNs>(i));
    StereoFrame frame;
    frame.left.image = i == 0 ? std::move(first_left) : read_camera_image(lp, rig.left(), bayer);
    frame.right.image = i == 0 ? std::move(first_right) : read_camera_image(rp, rig.right(), bayer);
    frame.left.camera = CameraId::kLeft;
    frame.right.camera = CameraId::kRight;
    frame.left.t_ns = frame.right.t_ns = frame.t_key_ns = t_ns;
    frame.left.sequence = frame.right.sequence = frame.pair_sequence = i;

    check(augmenter->augment(frame, sc.scene, result));
    augment_ms += total_ms(augmenter->timings());
    result.stats.t_ns = t_ns;
    write_frame_outputs(out_dir, {lp.stem().string(), rp.stem().string()}, result);
    csv.add(result.stats);
    all.push_back(result.stats);
  }

  if (pairs.size() == 1) {
    out << format_table1(
        all.front(), "Occlusion statistics: " + pairs[0].first.string() + " | " + pairs[0].second.string());
  } else {
    out << format_run_summary(all);
  }
  out << "Wrote " << pairs.size() << " stereo frame(s) to " << out_dir.string() << " (augmenter "
      << fmt_ms(augment_ms / static_cast<double>(pairs.size())) << " ms per stereo frame)\n";
  return kExitOk;
}

// ---- demo ---------------------------------------------------------------------------------------

const std::vector<OptionSpec>& demo_specs() {
  static const std::vector<OptionSpec> specs = {
      {"out", ArgKind::kValue, "DIR", "output folder (created)", true},
      {"frames", ArgKind::kValue, "N", "stereo frames of the approach, at 30 fps (default 90)"},
      {"rig", ArgKind::kValue, "RIG.yaml|default", "rig file, or 'default' for the paper's rig (default)"},
      {"bayer", ArgKind::kOptionalValue, "[=RG|GR|GB|BG]", "simulate raw Bayer cameras (default pattern RG)"},
      {"receiver-draw", ArgKind::kValue, "mask|wireframe|translucent",
       "how the receiver shows in the augmented image (default mask: not drawn)"},
  };
  return specs;
}

const char* kDemoUsage =
    "augrig demo --out DIR [--frames N] [--rig RIG.yaml] [--bayer] [--receiver-draw MODE]";
const char* kDemoSummary =
    "Flies a simulated approach from observation to contact, augments every stereo frame with its\n"
    "truth, writes stats.csv for every frame, images for every 10th frame and the last, and demo.png\n"
    "(a contact sheet of the last frame).";

int parse_frames(const std::string& v) {
  int n = 0;
  const auto r = std::from_chars(v.data(), v.data() + v.size(), n);
  if (r.ec != std::errc() || r.ptr != v.data() + v.size() || n < 1 || n > 100000) {
    usage_error("--frames: expected a whole number from 1 to 100000, got '" + v + "'");
  }
  return n;
}

// Next frame of the source; the simulation never times out, but a source may ask to be called again.
Frame next_frame(FrameSource& source, int stereo_index) {
  Frame f;
  for (int attempt = 0; attempt < 100; ++attempt) {
    const ReadStatus s = unwrap(source.read(f, std::chrono::milliseconds(100)));
    if (s == ReadStatus::kFrame) return f;
    if (s == ReadStatus::kEndOfStream) {
      runtime_error(source.uri() + ": ended early, at stereo frame " + std::to_string(stereo_index));
    }
  }
  runtime_error(source.uri() + ": no frame for 10 s");
}

// Half-size RGB copy of an image with a label in its top-left corner.
cv::Mat contact_tile(const Image& rgb, const std::string& label) {
  const cv::Mat full(rgb.height(), rgb.width(), CV_8UC3, const_cast<std::uint8_t*>(rgb.data()),
                     rgb.stride_bytes());
  cv::Mat half;
  cv::resize(full, half, cv::Size(rgb.width() / 2, rgb.height() / 2), 0, 0, cv::INTER_AREA);
  // Dark band under the label keeps it readable over sky and ground alike.
  const int scale_px = std::max(1, half.rows / 480);
  cv::rectangle(half, cv::Rect(0, 0, half.cols, 28 * scale_px), cv::Scalar(0, 0, 0), cv::FILLED);
  cv::putText(half, label, cv::Point(8 * scale_px, 20 * scale_px), cv::FONT_HERSHEY_SIMPLEX, 0.6 * scale_px,
              cv::Scalar(255, 255, 255), scale_px, cv::LINE_AA);
  return half;
}

// demo.png: a 2x2 montage of the last frame (images are RGB here; converted to BGR on write).
Image contact_sheet(const Frame& raw_left, const StereoResult& r) {
  const Image raw = to_rgb8(raw_left.image);
  const cv::Mat tiles[4] = {
      contact_tile(to_rgb8(r.left.augmented), "left camera, augmented"),
      contact_tile(to_rgb8(r.right.augmented), "right camera, augmented"),
      contact_tile(blend_over(raw, visualize_boom_overlap(r.left.mask, r.right.mask)),
                   "boom: left cyan, right blue, both green"),
      contact_tile(blend_over(raw, visualize_receiver_occlusion(r.left.mask, true)),
                   "left: receiver red, boom cyan, boom over receiver white"),
  };
  cv::Mat top, bottom, sheet;
  cv::hconcat(tiles[0], tiles[1], top);
  cv::hconcat(tiles[2], tiles[3], bottom);
  cv::vconcat(top, bottom, sheet);
  Image out(sheet.cols, sheet.rows, PixelFormat::kRGB8);
  for (int y = 0; y < sheet.rows; ++y) std::copy_n(sheet.ptr<std::uint8_t>(y), 3 * sheet.cols, out.row(y));
  return out;
}

int demo(const std::vector<std::string>& args, std::ostream& out) {
  const ParsedArgs a = [&] {
    auto p = parse_args(args, demo_specs());
    if (!p) usage_error(p.error().message);
    return *p;
  }();
  if (a.help) {
    out << format_help(kDemoUsage, kDemoSummary, demo_specs());
    return kExitOk;
  }
  const int frames = a.has("frames") ? parse_frames(a.get("frames")) : 90;
  ApproachOptions approach;
  approach.frames = frames;
  approach.fps = 30.0;
  if (a.has("bayer")) approach.sensor.format = parse_bayer(a.get("bayer").empty() ? "RG" : a.get("bayer"));
  AugmentOptions options;
  options.receiver_draw = parse_receiver_draw(a.get("receiver-draw"));
  const Rig rig = load_rig_arg(a.get("rig", "default"));
  if (rig.cameras.size() != 2)
    runtime_error(rig.source + ": the rig needs 2 cameras, has " + std::to_string(rig.cameras.size()));

  const fs::path out_dir = a.get("out");
  make_dirs(out_dir);
  StatsCsv csv(out_dir / "stats.csv");

  const auto t_start = Clock::now();
  const auto gl = make_gl_context();
  const auto source = unwrap(ApproachSource::create(rig, approach));
  const auto augmenter = unwrap(Augmenter::create(rig, options));
  out << "demo: " << frames << " stereo frames of " << source->uri() << ", "
      << to_string(approach.sensor.format) << ", " << rig.left().model.width_px << "x"
      << rig.left().model.height_px << " -> " << out_dir.string() << "\n";

  StereoResult result;
  StereoFrame stereo;
  // Frames go through the same pairing as live capture: by mid-exposure time within half a period.
  StereoPairer pairer(s_to_ns(0.5 / approach.fps));
  std::vector<OcclusionStats> all;
  double sim_ms = 0, augment_ms = 0, write_ms = 0;
  for (int i = 0; i < frames; ++i) {
    auto t0 = Clock::now();
    std::optional<StereoFrame> paired;
    for (int k = 0; !paired; ++k) {
      if (k > 8) runtime_error(source->uri() + ": no stereo pair at stereo frame " + std::to_string(i));
      paired = pairer.push(next_frame(*source, i));
    }
    stereo = std::move(*paired);
    sim_ms += ms_since(t0);
    if (stereo.left.sequence != stereo.right.sequence)
      runtime_error(source->uri() + ": paired frames of different sequences at stereo frame " +
                    std::to_string(i));
    const ApproachTruth& truth = source->truth(stereo.left.sequence);

    check(augmenter->augment(stereo, truth.scene, result));
    augment_ms += total_ms(augmenter->timings());
    result.stats.t_ns = truth.t_ns;
    csv.add(result.stats);
    all.push_back(result.stats);

    // Images for a subset only: PNG encoding costs more than the augmentation itself.
    const bool last = i + 1 == frames;
    if (i % 10 == 0 || last) {
      t0 = Clock::now();
      char stem[32];
      std::snprintf(stem, sizeof stem, "frame_%04d", i);
      write_frame_outputs(out_dir, {stem, stem}, result);
      write_ms += ms_since(t0);
    }
    if ((i + 1) % 10 == 0 || last) {
      const OcclusionStats& s = result.stats;
      char line[200];
      std::snprintf(line, sizeof line,
                    "frame %4d/%d  t %6.3f s  receiver %7lld px  boom %7lld px  occluded %5.1f%% (left)\n",
                    i + 1, frames, ns_to_s(truth.t_ns), static_cast<long long>(s.receiver_px_left),
                    static_cast<long long>(s.boom_px_left), s.occluded_pct_left);
      out << line << std::flush;
    }
  }

  auto t0 = Clock::now();
  check(write_image_file((out_dir / "demo.png").string(), contact_sheet(stereo.left, result), 3));
  write_ms += ms_since(t0);

  out << "\n" << format_run_summary(all) << "\n";
  out << format_table1(all.back(),
                       "Last frame (contact), t = " + std::to_string(ns_to_s(all.back().t_ns)) + " s");
  const double n = frames;
  out << "\nTiming: augmenter " << fmt_ms(augment_ms / n)
      << " ms per stereo frame (wall time of render, masks, composite and stats), "
      << "simulation " << fmt_ms(sim_ms / n) << " ms per stereo frame, PNG writing " << fmt_ms(write_ms)
      << " ms in all, total " << fmt_ms(ms_since(t_start) / 1000.0) << " s\n";
  pairer.flush();
  out << "Pairing: " << pairer.stats().pairs << " pairs, unpaired left " << pairer.stats().unpaired_left
      << ", right " << pairer.stats().unpaired_right << ", max |skew| " << pairer.stats().max_abs_skew_ns
      << " ns\n";
  out << "Wrote " << (out_dir / "stats.csv").string() << " and " << (out_dir / "demo.png").string() << "\n";
  return kExitOk;
}

// ---- Top level ------------------------------------------------------------------------------------

const char* kTopHelp =
    "augrig: augments stereo flight-test images with a virtual refuelling boom, exact per-pixel masks\n"
    "and occlusion statistics.\n"
    "\n"
    "Usage: augrig <command> [options]     (augrig <command> --help for its options)\n"
    "\n"
    "Commands:\n"
    "  augment   augment a stereo pair, or folders of pairs, with a scene file\n"
    "  demo      simulate an approach to contact, augment it, write stats and a contact sheet\n"
    "\n"
    "Options:\n"
    "  --help, -h   this help\n"
    "  --version    print the version\n"
    "\n"
    "Exit codes: 0 ok, 1 runtime error (bad input content, OpenGL failure), 2 usage error.\n"
    "Documentation: docs/CLI.md\n";

}  // namespace

// ---- Argument parsing ---------------------------------------------------------------------------

Expected<ParsedArgs> parse_args(const std::vector<std::string>& args, const std::vector<OptionSpec>& specs) {
  ParsedArgs p;
  auto find = [&](const std::string& name) -> const OptionSpec* {
    for (const auto& s : specs)
      if (s.name == name) return &s;
    return nullptr;
  };
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (arg == "--help" || arg == "-h") {
      p.help = true;
      continue;
    }
    if (arg.rfind("--", 0) != 0 || arg.size() == 2) {
      return make_error("unexpected argument '", arg, "' (options are --name VALUE; see --help)");
    }
    // "--name=value" or "--name [value]".
    const auto eq = arg.find('=');
    const std::string name = arg.substr(2, eq == std::string::npos ? std::string::npos : eq - 2);
    const OptionSpec* spec = find(name);
    if (!spec) return make_error("unknown option '--", name, "' (see --help)");
    if (p.has(name)) return make_error("option '--", name, "' given twice");
    std::string value;
    if (eq != std::string::npos) {
      if (spec->kind == ArgKind::kFlag) return make_error("option '--", name, "' takes no value");
      value = arg.substr(eq + 1);
    } else if (spec->kind == ArgKind::kValue) {
      if (i + 1 >= args.size())
        return make_error("option '--", name, "' needs a value: --", name, " ", spec->metavar);
      value = args[++i];
    }
    if (spec->kind == ArgKind::kValue && value.empty()) {
      return make_error("option '--", name, "' needs a non-empty value: --", name, " ", spec->metavar);
    }
    p.values[name] = value;
  }
  if (!p.help) {
    for (const auto& s : specs) {
      if (s.required && !p.has(s.name))
        return make_error("missing required option --", s.name, " ", s.metavar);
    }
  }
  return p;
}

std::string format_help(const std::string& usage, const std::string& summary,
                        const std::vector<OptionSpec>& specs) {
  std::ostringstream o;
  o << "Usage: " << usage << "\n\n" << summary << "\n\nOptions:\n";
  for (const auto& s : specs) {
    std::string left = "  --" + s.name;
    if (!s.metavar.empty()) left += (s.kind == ArgKind::kOptionalValue ? "" : " ") + s.metavar;
    o << left;
    if (left.size() < 36) {
      o << std::string(36 - left.size(), ' ');
    } else {
      o << "\n" << std::string(36, ' ');
    }
    o << s.help << (s.required ? " (required)" : "") << "\n";
  }
  o << "  --help, -h" << std::string(24, ' ') << "this help\n";
  return o.str();
}

// ---- Images -------------------------------------------------------------------------------------

Expected<Image> read_image_file(const std::string& path, std::optional<PixelFormat> bayer) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return make_error(path, ": no such file");
  if (fs::is_directory(path, ec)) return make_error(path, ": is a folder, expected an image file");
  cv::Mat m;
  try {
    m = cv::imread(path, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    return make_error(path, ": cannot decode the image (", e.what(), ")");
  }
  if (m.empty())
    return make_error(path, ": cannot read the image (unreadable, corrupt or not an image format)");
  const char* expected = "expected an 8-bit image: gray (Mono8 or a Bayer mosaic), BGR or BGRA";
  if (m.depth() != CV_8U) {
    const int bits = m.depth() == CV_16U || m.depth() == CV_16S ? 16 : (m.depth() == CV_8S ? 8 : 32);
    return make_error(path, ": has ", bits, "-bit samples; ", expected);
  }
  PixelFormat format;
  cv::Mat rgb;
  switch (m.channels()) {
    case 1:
      format = bayer ? *bayer : PixelFormat::kMono8;
      break;
    case 3:
      if (bayer) return make_error(path, ": has 3 channels, but --bayer expects 8-bit gray raw mosaics");
      format = PixelFormat::kRGB8;
      cv::cvtColor(m, rgb, cv::COLOR_BGR2RGB);  // OpenCV reads BGR
      m = rgb;
      break;
    case 4:
      if (bayer) return make_error(path, ": has 4 channels, but --bayer expects 8-bit gray raw mosaics");
      format = PixelFormat::kRGBA8;
      cv::cvtColor(m, rgb, cv::COLOR_BGRA2RGBA);
      m = rgb;
      break;
    default:
      return make_error(path, ": has ", m.channels(), " channels; ", expected);
  }
  Image im(m.cols, m.rows, format);
  const std::size_t row_bytes = static_cast<std::size_t>(m.cols) * bytes_per_pixel(format);
  for (int y = 0; y < m.rows; ++y) std::copy_n(m.ptr<std::uint8_t>(y), row_bytes, im.row(y));
  return im;
}

Status write_image_file(const std::string& path, const Image& image, int png_compression) {
  if (image.empty()) return make_error(path, ": nothing to write (empty image)");
  const int channels = bytes_per_pixel(image.format());
  const cv::Mat m(image.height(), image.width(), CV_8UC(channels), const_cast<std::uint8_t*>(image.data()),
                  image.stride_bytes());
  // OpenCV writes BGR. Convert into a buffer of its own: `m` wraps the caller's pixels, which must
  // come back unchanged (the demo builds its contact sheet from frames it has just written).
  cv::Mat bgr;
  if (image.format() == PixelFormat::kRGB8)
    cv::cvtColor(m, bgr, cv::COLOR_RGB2BGR);
  else if (image.format() == PixelFormat::kRGBA8)
    cv::cvtColor(m, bgr, cv::COLOR_RGBA2BGRA);
  else
    bgr = m;
  std::error_code ec;
  const fs::path parent = fs::path(path).parent_path();
  if (!parent.empty()) fs::create_directories(parent, ec);
  if (ec) return make_error(parent.string(), ": cannot create the folder (", ec.message(), ")");
  try {
    if (!cv::imwrite(path, bgr, {cv::IMWRITE_PNG_COMPRESSION, png_compression})) {
      return make_error(path, ": cannot write the image");
    }
  } catch (const cv::Exception& e) {
    return make_error(path, ": cannot write the image (", e.what(), ")");
  }
  return {};
}

// ---- Commands -----------------------------------------------------------------------------------

namespace {
// Runs a command body, turning its errors (and anything unexpected) into one stderr line and an exit code.
template <typename Body>
int guarded(const std::string& command, std::ostream& err, Body&& body) {
  try {
    return body();
  } catch (const CommandError& e) {
    // One line: the message, and for usage errors where to look.
    err << "augrig " << command << ": " << e.message
        << (e.code == kExitUsage ? " (see augrig " + command + " --help)" : std::string()) << "\n";
    return e.code;
  } catch (const std::exception& e) {
    err << "augrig " << command << ": internal error: " << e.what() << "\n";
    return kExitRuntime;
  }
}
}  // namespace

int cmd_augment(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("augment", err, [&] { return augment(args, out); });
}

int cmd_demo(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("demo", err, [&] { return demo(args, out); });
}

int run_cli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  if (args.empty()) {
    err << kTopHelp;
    return kExitUsage;
  }
  const std::string& command = args[0];
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (command == "--help" || command == "-h" || command == "help") {
    out << kTopHelp;
    return kExitOk;
  }
  if (command == "--version") {
    out << "augrig " << AUGRIG_VERSION << "\n";
    return kExitOk;
  }
  if (command == "augment") return cmd_augment(rest, out, err);
  if (command == "demo") return cmd_demo(rest, out, err);
  err << "augrig: unknown command '" << command << "'; commands: augment, demo (see augrig --help)\n";
  return kExitUsage;
}

}  // namespace augrig::app
