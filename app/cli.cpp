#include "app/cli.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "recorder/reader.hpp"
#include "render/visualize.hpp"

namespace augrig::app {

double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

void runtime_error(const std::string& what) {
  throw CommandError{kExitRuntime, what};
}
void usage_error(const std::string& what) {
  throw CommandError{kExitUsage, what};
}

std::string user_message(const Error& e) {
  const std::string& m = e.message;
  const auto end = m.find("(): ");
  if (end != std::string::npos && end < 48) {
    const std::string head = m.substr(0, end);
    if (head.find("::") != std::string::npos && head.find(' ') == std::string::npos) return m.substr(end + 4);
  }
  return m;
}

void check(const Status& s) {
  if (!s) runtime_error(user_message(s.error()));
}

// ---- Shared flag handling -----------------------------------------------------------------------

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

void write_png(const fs::path& path, const Image& image) {
  check(write_image_file(path.string(), image));
}

recorder::FrameRecord frame_record(const StereoResult& r) {
  recorder::FrameRecord fr;
  fr.augmented = {r.left.augmented, r.right.augmented};
  // The changed-box output made only the boxes (an image of the box's size).
  for (const ViewResult* v : {&r.left, &r.right})
    if (v->augmented.width() == v->augmented_box.width() &&
        v->augmented.height() == v->augmented_box.height())
      fr.augmented_box[v == &r.left ? 0 : 1] = v->augmented_box;
  fr.mask = {r.left.mask, r.right.mask};
  fr.stats = r.stats;
  return fr;
}

void write_frame_outputs(const fs::path& out, const FrameNames& n, const StereoFrame& raw,
                         const StereoResult& r) {
  const std::string l = n.left + ".png", rr = n.right + ".png";
  write_png(out / "left" / "augmented" / l, whole_augmented(raw.left.image, r.left));
  write_png(out / "right" / "augmented" / rr, whole_augmented(raw.right.image, r.right));
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

StatsCsv::StatsCsv(const fs::path& path) : path_(path), out_(path, std::ios::binary) {
  if (!out_) runtime_error(path.string() + ": cannot write the statistics file");
  write_stats_csv_header(out_);
}

void StatsCsv::add(const OcclusionStats& s) {
  write_stats_csv_row(out_, s);
  out_.flush();
  if (!out_) runtime_error(path_.string() + ": write failed");
}

std::string fmt_ms(double ms) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f", ms);
  return buf;
}

ParsedArgs parse_or_usage(const std::vector<std::string>& args, const std::vector<OptionSpec>& specs) {
  auto p = parse_args(args, specs);
  if (!p) usage_error(p.error().message);
  return *p;
}

long long parse_integer(const std::string& flag, const std::string& v, long long lo, long long hi) {
  long long n = 0;
  const auto r = std::from_chars(v.data(), v.data() + v.size(), n);
  if (r.ec != std::errc() || r.ptr != v.data() + v.size() || n < lo || n > hi) {
    usage_error("--" + flag + ": expected a whole number from " + std::to_string(lo) + " to " +
                std::to_string(hi) + ", got '" + v + "'");
  }
  return n;
}

double parse_real(const std::string& flag, const std::string& v) {
  char* end = nullptr;
  const double x = std::strtod(v.c_str(), &end);
  if (v.empty() || end != v.c_str() + v.size() || !std::isfinite(x))
    usage_error("--" + flag + ": expected a number, got '" + v + "'");
  return x;
}

BoomArg parse_boom_arg(const std::string& v) {
  BoomArg b;
  if (v.empty() || v == "track") return b;
  if (v.rfind("fixed:", 0) == 0) {
    double x[3];
    std::size_t pos = 6;
    for (int i = 0; i < 3; ++i) {
      const std::size_t end = i < 2 ? v.find(',', pos) : v.size();
      if (end == std::string::npos)
        usage_error("--boom fixed: expected fixed:EL_DEG,AZ_DEG,EXT_M, got '" + v + "'");
      x[i] = parse_real("boom", v.substr(pos, end - pos));
      pos = end + 1;
    }
    b.mode = BoomMode::kFixed;
    b.fixed = {deg_to_rad(x[0]), deg_to_rad(x[1]), x[2]};
    return b;
  }
  if (v.rfind("script:", 0) == 0) {
    b.mode = BoomMode::kScripted;
    b.script = unwrap(load_boom_script(v.substr(7)));
    return b;
  }
  usage_error("--boom: expected track, fixed:EL_DEG,AZ_DEG,EXT_M or script:FILE.csv, got '" + v + "'");
}

BoomCommand BoomArg::command(double t_s, const BoomCommand& tracked, const BoomLimits& limits) const {
  switch (mode) {
    case BoomMode::kFixed:
      return clamp_to_limits(fixed, limits);
    case BoomMode::kScripted:
      return clamp_to_limits(script.at(t_s), limits);
    case BoomMode::kTrackReceptacle:
      break;
  }
  return tracked;
}

// ---- Positional arguments and recordings --------------------------------------------------------

// Splits the positional arguments (neither an option nor an option's value) from the options.
static std::vector<std::string> split_positionals(const std::vector<std::string>& args,
                                           const std::vector<OptionSpec>& specs,
                                           std::vector<std::string>& options) {
  std::vector<std::string> pos;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "-h" || (a.rfind("--", 0) == 0 && a.size() > 2)) {
      options.push_back(a);
      if (a.find('=') != std::string::npos) continue;
      for (const OptionSpec& s : specs) {
        if (a.substr(2) == s.name && s.kind == ArgKind::kValue && i + 1 < args.size()) {
          options.push_back(args[++i]);
          break;
        }
      }
    } else {
      pos.push_back(a);
    }
  }
  return pos;
}

// The flags, and exactly the positionals `names` (for the message).
ParsedArgs parse_with_positionals(const std::vector<std::string>& args, const std::vector<OptionSpec>& specs,
                                  const std::vector<std::string>& names,
                                  std::vector<std::string>& positionals) {
  std::vector<std::string> options;
  positionals = split_positionals(args, specs, options);
  ParsedArgs a = parse_or_usage(options, specs);
  if (a.help) return a;
  if (positionals.size() != names.size()) {
    std::string want;
    for (const auto& n : names) want += (want.empty() ? "" : " ") + n;
    std::string got;
    for (const auto& p : positionals) got += (got.empty() ? "'" : ", '") + p + "'";
    usage_error("expected " + want + (positionals.empty() ? ", got none" : ", got " + got));
  }
  return a;
}

std::unique_ptr<recorder::RecordingReader> open_recording(const std::string& dir) {
  return unwrap(recorder::RecordingReader::open(dir));
}

// A problem of the recording as a whole (RecordingReader::problems()), naming its file.
std::string recording_problem(const recorder::RecordingReader& reader, const std::string& problem) {
  return problem.rfind(reader.path(), 0) == 0 ? problem : reader.path() + ": " + problem;
}

}  // namespace augrig::app
