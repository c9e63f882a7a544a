#include "app/cli.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "pipeline/nav_inputs.hpp"
#include "pipeline/sinks/registry.hpp"
#include "recorder/reader.hpp"
#include "recorder/recorder.hpp"
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

OptionSpec rig_option(const std::string& default_text, bool required) {
  return {"rig", ArgKind::kValue, "RIG.yaml|default",
          "the rig (docs/RIG_FORMAT.md: cameras, boom, receiver), or 'default' for the paper's" +
              (default_text.empty() ? std::string() : " (default: " + default_text + ")"),
          required};
}

OptionSpec scene_option(const std::string& default_text, bool folder) {
  return {"scene", ArgKind::kValue, folder ? "SCENE.yaml|DIR" : "SCENE.yaml",
          std::string("a fixed scene (boom articulation, receiver pose; docs/CLI.md)") +
              (folder ? "; a folder holds one scene file per pair (sorted)" : " for every frame") +
              (default_text.empty() ? std::string() : " (default: " + default_text + ")")};
}

OptionSpec allow_damaged_option() {
  return {"allow-damaged", ArgKind::kFlag, "",
          "input frames that cannot be read are reported and left out of the outputs, and the command still "
          "exits 0 (campaign tasks)"};
}

void input_damage(const ParsedArgs& a, const std::string& command, const std::string& what,
                  std::ostream& err) {
  if (!a.has("allow-damaged")) runtime_error(what);
  err << "augrig " << command << ": " << what << " (--allow-damaged: the command succeeds)\n";
}

void recording_damage(const ParsedArgs& a, const std::string& command, bool incomplete,
                      std::uint64_t unreadable, const std::string& done, std::ostream& err) {
  const std::string others = "the others were " + done;
  if (incomplete)
    input_damage(a, command,
                 "the recording is incomplete (above); " +
                     (unreadable ? std::to_string(unreadable) + " listed frame(s) could not be read, "
                                 : std::string()) +
                     others,
                 err);
  else if (unreadable)
    input_damage(a, command, std::to_string(unreadable) + " frame(s) could not be read (above); " + others,
                 err);
}

OptionSpec poses_option(const std::string& extra) {
  return {"poses", ArgKind::kValue, "POSES.csv",
          "the receiver's pose per frame from `augrig nav`'s camera pose CSV, matched to the left frame's "
          "timestamp" +
              (extra.empty() ? std::string() : "; " + extra)};
}

OptionSpec pose_tolerance_option() {
  return {"pose-tolerance-ms", ArgKind::kValue, "MS",
          "with --poses: match a pose row within MS of the left frame's timestamp (default 0: exactly)"};
}

OptionSpec boom_option(const std::string& default_text) {
  return {
      "boom", ArgKind::kValue, "track|fixed:EL,AZ,EXT|script:FILE.csv",
      "boom articulation: tracking the receptacle, fixed (degrees, degrees, metres) or a script (default: " +
          default_text + ")"};
}

OptionSpec receiver_draw_option() {
  return {"receiver-draw", ArgKind::kValue, "mask|wireframe|translucent",
          "how the receiver shows in the augmented image (default mask: not drawn)"};
}

OptionSpec look_option() {
  return {
      "look", ArgKind::kValue, "plain|camera",
      "the boom's look: camera (sun and sky, the camera's PSF and sensor noise estimated from its frames) "
      "or plain (a clean rendering under a fixed light); default camera (docs/LOOK.md)"};
}

OptionSpec sink_option() {
  std::string help = "another output, repeatable:";
  for (const std::string& u : pipeline::sink_usages()) help += "\n  " + u;
  OptionSpec spec{"sink", ArgKind::kValue, "SCHEME:ARG", help};
  spec.repeatable = true;
  return spec;
}

void apply_sink_args(const ParsedArgs& a, pipeline::PipelineParts& parts, const std::string& replayed) {
  for (const std::string& spec : a.all("sink")) {
    auto sink = pipeline::make_sink(spec, {parts.rig, {}, nullptr, replayed});
    if (!sink) usage_error(sink.error().message);
    parts.sinks.push_back(std::move(*sink));
  }
}

void apply_look_arg(const ParsedArgs& a, const Rig& rig, AugmentOptions& options) {
  const std::string v = a.get("look", "camera");
  if (!parse_look(v, options.look)) usage_error("--look: expected plain or camera, got '" + v + "'");
  options.camera_looks.clear();
  for (const RigCamera& c : rig.cameras) options.camera_looks.push_back(c.look);
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

void write_frame_outputs(const fs::path& out, const FrameNames& n, const StereoFrame& raw,
                         const StereoResult& r) {
  check(write_frame_images(out, n, raw, r));
}

StatsCsv::StatsCsv(const fs::path& path) : writer_(unwrap(StatsCsvWriter::create(path))) {}

void StatsCsv::add(const OcclusionStats& s) {
  check(writer_->add(s));
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

std::vector<std::pair<std::string, std::string>> parse_named_list_arg(const std::string& v,
                                                                      const std::string& what) {
  auto items = parse_named_list(v, what);
  if (!items) usage_error(items.error().message);
  return *items;
}

bool display_present() {
  const char* d = std::getenv("DISPLAY");
  return d && *d;
}

TimestampNs parse_pose_tolerance(const ParsedArgs& a) {
  if (!a.has("pose-tolerance-ms")) return 0;
  const double ms = parse_real("pose-tolerance-ms", a.get("pose-tolerance-ms"));
  if (!(ms >= 0) || ms > 1e6) usage_error("--pose-tolerance-ms: expected milliseconds in [0, 1e6]");
  return s_to_ns(ms / 1e3);
}

std::uint64_t parse_screenshot_at(const ParsedArgs& a) {
  return a.has("screenshot-at") ? static_cast<std::uint64_t>(
                                      parse_integer("screenshot-at", a.get("screenshot-at"), 1, 1LL << 40))
                                : 0;
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

std::unique_ptr<recorder::Recorder> create_recorder(const std::string& dir,
                                                    const recorder::RecordingInfo& info, bool overwrite) {
  const fs::path db = fs::path(dir) / "recording.sqlite";
  if (!overwrite && fs::exists(db))
    runtime_error(db.string() +
                  ": a recording is already there; give --overwrite to replace it, or another folder");
  recorder::RecorderOptions o;
  o.overwrite = overwrite;
  return unwrap(recorder::Recorder::create(dir, info, o));
}

std::unique_ptr<recorder::RecordingReader> open_recording(const std::string& dir) {
  return unwrap(recorder::RecordingReader::open(dir));
}

// A problem of the recording as a whole (RecordingReader::problems()), naming its file.
std::string recording_problem(const recorder::RecordingReader& reader, const std::string& problem) {
  return problem.rfind(reader.path(), 0) == 0 ? problem : reader.path() + ": " + problem;
}

}  // namespace augrig::app
