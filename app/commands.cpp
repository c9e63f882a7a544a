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

#include "app/cli.hpp"
#include "pipeline/scene_file.hpp"
#include "capture/stereo_pairer.hpp"
#include "core/frame.hpp"
#include "render/augmenter.hpp"
#include "render/gl_context.hpp"
#include "render/image_file.hpp"
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
    augment_ms += augmenter->timings().total_ms;
    result.stats.t_ns = t_ns;
    write_frame_outputs(out_dir, {lp.stem().string(), rp.stem().string()}, frame, result);
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
      << fmt_ms(augment_ms / static_cast<double>(pairs.size())) << " ms per stereo frame, "
      << to_string(augmenter->rasterizer()) << " rasteriser)\n";
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
    "  demo      fly a simulated approach end to end: sim, nav fusion, boom tracking, augmentation\n"
    "  sim       simulate a flight: truth, GPS/IMU logs (NMEA, CSV), rendered stereo frames\n"
    "  nav       fuse both aircraft's GPS/IMU logs into the receiver's pose in each camera per frame\n"
    "  check     check a recording: what it holds, what is damaged (exit 1 if anything is)\n"
    "  replay    replay a recording through the augmenter (recorded or another rig and scene)\n"
    "  export    export a recording as a EuRoC/ASL dataset with poses, statistics and their plot\n"
    "  cameras   list the GigE Vision, USB3 Vision and V4L2 cameras this machine sees\n"
    "  run       the live pipeline from source URIs: capture, pairing, augmentation, recording\n"
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
  std::error_code ec;
  const fs::path parent = fs::path(path).parent_path();
  if (!parent.empty()) fs::create_directories(parent, ec);
  if (ec) return make_error(parent.string(), ": cannot create the folder (", ec.message(), ")");
  return write_png_file(path, image, png_compression);
}

// ---- Commands -----------------------------------------------------------------------------------

int cmd_augment(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("augment", err, [&] { return augment(args, out); });
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
  if (command == "sim") return cmd_sim(rest, out, err);
  if (command == "nav") return cmd_nav(rest, out, err);
  if (command == "check") return cmd_check(rest, out, err);
  if (command == "replay") return cmd_replay(rest, out, err);
  if (command == "export") return cmd_export(rest, out, err);
  if (command == "cameras") return cmd_cameras(rest, out, err);
  if (command == "run") return cmd_run(rest, out, err);
  err << "augrig: unknown command '" << command
      << "'; commands: augment, demo, sim, nav, check, replay, export, cameras, run (see augrig --help)\n";
  return kExitUsage;
}

}  // namespace augrig::app
