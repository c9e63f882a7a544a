// augrig demo: the main job. (Rewritten as a whole simulated flight in issue 3.)
#include <charconv>
#include <optional>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "app/cli.hpp"
#include "capture/stereo_pairer.hpp"
#include "render/visualize.hpp"
#include "sim/approach.hpp"

namespace augrig::app {
namespace {

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
    augment_ms += augmenter->timings().total_ms;
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

}  // namespace

int cmd_demo(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("demo", err, [&] { return demo(args, out); });
}

}  // namespace augrig::app
