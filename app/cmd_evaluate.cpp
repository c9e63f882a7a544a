// augrig evaluate SOURCE: what the boom does to stereo matching (docs/EVALUATE.md). The source's
// pairs go through the pipeline as in `replay` or `run` (augmented with the recorded, simulated or
// given poses); every K-th augmented pair is then evaluated (eval/evaluator.hpp: the raw and the
// augmented pair rectified, matched and scored against the true disparity per stereo class). At the
// end the run's table is printed; with --out also evaluation.txt, the per-frame evaluation.csv and
// evaluation_sums.csv, stats.csv, the plot evaluation.png and, with --images K, disparity images.
//
// A run can be split into parts (issue 21: a campaign's shards) whose files, one after the other,
// are the whole run's: a frame is named and selected by its index in the source (recording order),
// its time counts from the source's first frame, and --frames ends a recording's or EuRoC folder's
// range in the source (frames --from-frame .. + N - 1, whatever in it is skipped).
//
// --look plain|camera draws the boom in that look (as `run`, `replay`); --look physical (issue 33
// §3, simulated flights only) scores the simulator's frames with the boom physically in the scene
// as the augmented pair, the augmenter (plain look) still making the masks, depth and classes.
#include <cmath>
#include <limits>
#include <optional>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "app/cli.hpp"
#include "app/window_runner.hpp"
#include "capture/source_uri.hpp"
#include "eval/evaluator.hpp"
#include "eval/report.hpp"
#include "pipeline/image_folder_source.hpp"
#include "pipeline/scene_file.hpp"
#include "recorder/mcap_source.hpp"
#include "recorder/reader.hpp"
#include "recorder/replay_source.hpp"
#include "sim/flight_source.hpp"

namespace augrig::app {
namespace {

const std::vector<OptionSpec>& evaluate_specs() {
  static const std::vector<OptionSpec> specs = {
      {"matcher", ArgKind::kValue, "MATCHER.yaml",
       "the stereo matcher and its parameters (docs/EVALUATE.md; default StereoSGBM 3-way, 64 disparities, "
       "block 5)"},
      {"out", ArgKind::kValue, "DIR",
       "write evaluation.txt (the table), evaluation.csv (per frame), evaluation_sums.csv (per frame, "
       "exact), "
       "stats.csv and evaluation.png here"},
      {"every", ArgKind::kValue, "K",
       "evaluate the frames whose index in the source is a multiple of K (default 1: all)"},
      {"frames", ArgKind::kValue, "N",
       "recordings and EuRoC folders: frames START..START+N-1 of the source; else stop after N augmented "
       "stereo frames"},
      {"images", ArgKind::kValue, "K",
       "with --out: the true, raw and augmented disparity of every K-th evaluated frame (16-bit PNG, "
       "disparity x 256, 0 none; and a colour view)"},
      rig_option("the recording's, the scenario's, or the paper's for a frame index or EuRoC folder"),
      scene_option("the source's poses"),
      poses_option(),
      pose_tolerance_option(),
      {"boom", ArgKind::kValue, "track|fixed:EL,AZ,EXT|script:FILE.csv|scenario",
       "boom articulation: tracking the receptacle, fixed (degrees, degrees, metres), a script, or "
       "scenario: a simulated flight's own boom (the one --look physical shows) (default: the source's: "
       "recorded, the scenario's with --look physical, else tracking)"},
      {"look", ArgKind::kValue, "plain|camera|physical",
       "the augmented pair's boom: drawn in the camera look (sun and sky, the camera's PSF and noise; "
       "docs/LOOK.md) or the plain one, or physical: a simulated flight's frames with the boom in the "
       "scene (sim:// only); default camera"},
      {"from-frame", ArgKind::kValue, "N", "recordings and EuRoC folders: start at frame N"},
      {"seek", ArgKind::kValue, "T_S",
       "recordings and EuRoC folders: start T_S seconds after the first frame"},
      {"full-frame", ArgKind::kFlag, "", "match whole rectified frames, not the receiver's region (slower)"},
      {"context", ArgKind::kValue, "PX",
       "image matched around the receiver beyond the search range and block (default 128)"},
      {"no-plot", ArgKind::kFlag, "", "with --out: no evaluation.png (it needs gnuplot)"},
      {"pair-tolerance-ns", ArgKind::kValue, "NS",
       "EuRoC folders: pair frames whose timestamps differ by at most NS (default 0)"},
      allow_damaged_option(),
  };
  return specs;
}

// A disparity image as KITTI writes it: 16-bit, disparity x 256, 0 where none.
void write_disparity_png(const fs::path& path, const cv::Mat& d) {
  cv::Mat out(d.size(), CV_16UC1, cv::Scalar(0));
  for (int y = 0; y < d.rows; ++y) {
    const float* s = d.ptr<float>(y);
    std::uint16_t* o = out.ptr<std::uint16_t>(y);
    for (int x = 0; x < d.cols; ++x)
      if (std::isfinite(s[x]) && s[x] > 0)
        o[x] = static_cast<std::uint16_t>(std::min(65535.0f, std::round(s[x] * 256)));
  }
  if (!cv::imwrite(path.string(), out, {cv::IMWRITE_PNG_COMPRESSION, 1}))
    runtime_error(path.string() + ": cannot write the disparity image");
}

// True | raw | augmented disparity side by side, colour-mapped over the true disparity's range
// (black: none), for a person to look at.
void write_disparity_view(const fs::path& path, const eval::EvaluationImages& im, const cv::Rect& roi) {
  const cv::Rect r = roi.empty() ? cv::Rect(0, 0, im.true_disparity.cols, im.true_disparity.rows) : roi;
  double lo = 0, hi = 1;
  cv::Mat t = im.true_disparity(r).clone();
  cv::patchNaNs(t, 0);
  cv::minMaxLoc(t, nullptr, &hi);
  if (!(hi > lo)) hi = lo + 1;
  cv::Mat row;
  std::vector<cv::Mat> parts;
  for (const cv::Mat* d : {&im.true_disparity, &im.raw_disparity, &im.aug_disparity}) {
    const cv::Mat c = (*d)(r);
    cv::Mat u8(c.size(), CV_8UC1), valid(c.size(), CV_8UC1);
    for (int y = 0; y < c.rows; ++y)
      for (int x = 0; x < c.cols; ++x) {
        const float v = c.at<float>(y, x);
        valid.at<std::uint8_t>(y, x) = std::isfinite(v) ? 255 : 0;
        u8.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(
            std::isfinite(v) ? std::clamp((v - lo) / (hi - lo) * 255.0, 0.0, 255.0) : 0);
      }
    cv::Mat colour;
    cv::applyColorMap(u8, colour, cv::COLORMAP_TURBO);
    cv::Mat black(c.size(), CV_8UC3, cv::Scalar(0, 0, 0));
    colour.copyTo(black, valid);
    parts.push_back(black);
  }
  cv::hconcat(parts, row);
  if (!cv::imwrite(path.string(), row)) runtime_error(path.string() + ": cannot write the disparity view");
}

// The value of `key` in a source URI's query, if it parses and has one (a URI that does not parse
// is reported when the source is opened).
std::optional<std::string> uri_param(const std::string& uri, const std::string& key) {
  const auto u = parse_source_uri(uri);
  if (!u || !u->has(key)) return std::nullopt;
  return u->get(key);
}

// A simulated flight's truth with the scenario's own boom as the boom (the simulator's, where
// --look physical draws it), not as tracking's starting point.
class ScenarioBoomPoses final : public PoseProvider {
 public:
  explicit ScenarioBoomPoses(std::unique_ptr<PoseProvider> truth) : truth_(std::move(truth)) {}
  std::string describe() const override { return truth_->describe() + ", the scenario's boom"; }
  FramePoses at(const StereoFrame& frame, TimestampNs mid_host_left_ns) override {
    FramePoses p = truth_->at(frame, mid_host_left_ns);
    p.boom_given = p.scene.has_value();
    return p;
  }

 private:
  std::unique_ptr<PoseProvider> truth_;
};

// What the table's title says of the augmented pair's boom.
std::string look_text(const std::string& look) {
  if (look == "physical") return "look: physical boom (the simulator's frames with the boom in the scene)";
  if (look == "plain") return "look: plain (the boom drawn in, a clean rendering under a fixed light)";
  return "look: camera (the boom drawn in with the sun and sky, the camera's PSF and noise)";
}

void print_evaluate_help(std::ostream& out) {
  out << format_help(
      "augrig evaluate SOURCE [--matcher MATCHER.yaml] [--out DIR] [--every K] [--frames N] [--images K]\n"
      "                       [--look plain|camera|physical]",
      "SOURCE: a recording (DIR or replay://DIR), a simulated flight (sim://SCENARIO, e.g. sim://demo), a\n"
      "sequence (a frame index INDEX.csv as `augrig sim` writes it), or a EuRoC/ASL folder (the last two "
      "with\n"
      "--poses or --scene). Each stereo frame is augmented as `replay`/`run` would\n"
      "(recorded, simulated or given poses); those whose index in the source is a multiple of K are\n"
      "evaluated: the raw and the augmented pair are rectified, matched (OpenCV StereoSGBM or StereoBM)\n"
      "and compared with the true disparity over the receiver, per stereo class (both, left only, right\n"
      "only, neither), with the boom's pixels kept and left out. Prints the run's table (the seed paper's\n"
      "Table 1 rows with the matcher's errors); --out writes it with a CSV row per frame and the plots\n"
      "(docs/EVALUATE.md). Rows are named by the source's frame index and timed from its first frame:\n"
      "--from-frame A --frames N writes the whole run's rows of those frames.\n"
      "--look: the boom of the augmented pair: camera (default) or plain as `run` draws it, or physical\n"
      "(sim:// only): the simulator's frames with the boom in the scene are the augmented pair (and the\n"
      "raw one: both columns score the same frames); the masks, depth and classes come from the\n"
      "augmenter as always, flying the scenario's boom (--boom scenario, which plain and camera runs of\n"
      "a sim:// flight may give too). scripts/evaluate_looks.sh compares the three on one flight.",
      evaluate_specs());
}

// The flags that need no source.
struct EvaluateFlags {
  int every = 1;
  long long max_pairs = 0;  // --frames; 0: all
  int images_every = 0;     // --images; 0: none
  std::string look;
  bool physical = false;
  eval::EvaluatorOptions eo;
};

// Flags first: nothing is opened for a command line that cannot work.
EvaluateFlags parse_evaluate_flags(const ParsedArgs& a) {
  EvaluateFlags f;
  f.every = a.has("every") ? static_cast<int>(parse_integer("every", a.get("every"), 1, 1000000)) : 1;
  f.max_pairs = a.has("frames") ? parse_integer("frames", a.get("frames"), 1, 1LL << 40) : 0;
  f.images_every =
      a.has("images") ? static_cast<int>(parse_integer("images", a.get("images"), 1, 1000000)) : 0;
  if (f.images_every && !a.has("out")) usage_error("--images needs --out (where the images go)");
  if (a.has("no-plot") && !a.has("out")) usage_error("--no-plot needs --out (the plot is written there)");
  if (a.has("scene") && a.has("poses")) usage_error("--scene and --poses are two sources of poses: give one");
  if (a.has("seek") && a.has("from-frame")) usage_error("--seek and --from-frame exclude each other");
  if (a.has("pose-tolerance-ms") && !a.has("poses")) usage_error("--pose-tolerance-ms needs --poses");
  if (a.has("full-frame") && a.has("context")) usage_error("--full-frame and --context exclude each other");
  f.look = a.get("look", "camera");
  if (f.look != "plain" && f.look != "camera" && f.look != "physical")
    usage_error("--look: expected plain, camera or physical, got '" + f.look + "'");
  f.physical = f.look == "physical";
  if (a.has("matcher")) f.eo.matcher = unwrap(eval::load_matcher_params(a.get("matcher")));
  f.eo.full_frame = a.has("full-frame");
  if (a.has("context"))
    f.eo.context_px = static_cast<int>(parse_integer("context", a.get("context"), 0, 100000));
  return f;
}

// What SOURCE names: a simulated flight, a frame index, a EuRoC folder or (none) a recording.
struct SourceKind {
  bool sim = false;
  bool index = false;
  bool euroc = false;
};

SourceKind classify_source(const std::string& src) {
  SourceKind k;
  k.sim = src.rfind("sim://", 0) == 0;
  // A sequence: a frame index (sequence,camera,t_ns,file) as `augrig sim` writes and `augment
  // --frames` reads, its frames paired by timestamp.
  k.index = !k.sim && (src.rfind("files://", 0) == 0 || fs::path(src).extension() == ".csv");
  k.euroc = !k.sim && !k.index &&
            (src.rfind("euroc://", 0) == 0 || fs::is_directory(fs::path(src) / "mav0") ||
             fs::path(src).filename() == "mav0");
  return k;
}

// --seek / --from-frame as the start parameters of a recording's or dataset's URI.
std::string start_params(const ParsedArgs& a, const SourceKind& kind) {
  std::string start;
  if ((a.has("seek") || a.has("from-frame")) && kind.index)
    usage_error("--seek and --from-frame: a frame index is evaluated whole (write a shorter index)");
  if (a.has("seek")) {
    if (kind.sim)
      usage_error("--seek: a simulated flight starts at its beginning (use the scenario's phases)");
    if (parse_real("seek", a.get("seek")) < 0)
      usage_error("--seek: expected seconds from the first frame (>= 0), got '" + a.get("seek") + "'");
    start = "&seek_s=" + a.get("seek");
  }
  if (a.has("from-frame")) {
    if (kind.sim) usage_error("--from-frame: a simulated flight starts at its beginning");
    start = "&from_frame=" + std::to_string(parse_integer("from-frame", a.get("from-frame"), 0, 1LL << 40));
  }
  return start;
}

// --look physical: checked against the other flags, and the simulated flight asked for its
// frames with the boom in the scene (boom=physical added to `src`).
void apply_physical_look(const ParsedArgs& a, const SourceKind& kind, std::string& src) {
  if (!kind.sim)
    usage_error(
        "--look physical: only a simulated flight (sim://SCENARIO) has frames with the boom in the "
        "scene; '" +
        src + "' is not one");
  // The boom in the frames is where the simulation puts it: the augmenter's (masks, classes) must
  // be the same one.
  if (a.has("boom") && a.get("boom") != "scenario")
    usage_error("--look physical and --boom " + a.get("boom") +
                ": the physical boom is the scenario's (--boom scenario), the masks must be of that boom");
  for (const char* flag : {"scene", "poses"})
    if (a.has(flag))
      usage_error(std::string("--look physical and --") + flag +
                  ": the physical boom and the receiver are the simulated flight's; the poses must be too");
  const auto boom = uri_param(src, "boom");
  if (boom && *boom != "physical")
    usage_error("--look physical: the source says boom=" + *boom +
                "; leave boom= out (or give boom=physical)");
  if (!boom) src += std::string(src.find('?') == std::string::npos ? "?" : "&") + "boom=physical";
}

// The URI that opens SOURCE for the run (`start`: start_params()).
std::string source_uri(const ParsedArgs& a, const std::string& src, const SourceKind& kind,
                       const std::string& start) {
  std::string uri;
  if (kind.sim) {
    // Every frame, as fast as the evaluation goes (lockstep: none dropped).
    uri = src + (src.find('?') == std::string::npos ? "?" : "&") +
          (src.find("rate=") == std::string::npos ? "rate=0" : "");
    if (uri.back() == '&' || uri.back() == '?') uri.pop_back();
  } else if (kind.index) {
    if (!a.has("scene") && !a.has("poses"))
      usage_error(
          "a frame index has no poses of the receiver: give --poses POSES.csv (e.g. augrig nav's, or a "
          "simulated dataset's truth/poses.csv) or --scene SCENE.yaml");
    const std::string path = src.rfind("files://", 0) == 0 ? src.substr(8) : src;
    if (!fs::is_regular_file(path)) runtime_error(path + ": no such frame index");
    uri = "files://" + fs::absolute(path).string();
  } else if (kind.euroc) {
    if (!a.has("scene") && !a.has("poses"))
      usage_error(
          "a EuRoC folder has no poses of the receiver: give --scene SCENE.yaml or --poses POSES.csv");
    const long long tol = a.has("pair-tolerance-ns")
                              ? parse_integer("pair-tolerance-ns", a.get("pair-tolerance-ns"), 0, 1LL << 40)
                              : 0;
    uri = "euroc://" + (src.rfind("euroc://", 0) == 0 ? src.substr(8) : src) +
          "?tolerance_ns=" + std::to_string(tol) + start;
  } else {
    const std::string dir = src.rfind("replay://", 0) == 0 ? src.substr(9) : src;
    if (!fs::exists(dir)) runtime_error(dir + ": no such recording, EuRoC folder or sim:// source");
    if (recorder::is_mcap_path(dir) && !start.empty())
      usage_error("--seek and --from-frame: an MCAP file is evaluated from its first frame");
    uri = "replay://" + dir + "?rate=fast" + start;
  }
  return uri;
}

// What the opened source says of itself: its rig, its length, and where its frames are counted
// and timed from (a frame index and a simulated flight: the run's first pair, see PairScorer),
// with --frames as the end of a recording's or EuRoC folder's range.
struct SourceFacts {
  std::optional<Rig> rig;
  std::uint64_t total_pairs = 0;
  std::optional<TimestampNs> origin_ns;
  std::optional<std::size_t> euroc_start;  // a EuRoC folder: its pair `sequence` is frame start + sequence
  bool range_in_source = false;
};

SourceFacts recording_facts(recorder::ReplaySource& replay, const ParsedArgs& a, long long max_pairs,
                            std::ostream& err) {
  SourceFacts f;
  const recorder::RecordingReader& reader = replay.reader();
  for (const std::string& p : reader.problems())
    err << "augrig evaluate: " << recording_problem(reader, p) << "\n";
  if (replay.frame_count() == 0) runtime_error(reader.path() + ": the recording holds no readable frames");
  if (const std::string yaml = reader.meta("rig_yaml"); !yaml.empty())
    f.rig = unwrap(parse_rig(yaml, reader.path() + " (meta rig_yaml)"));
  if (!f.rig && !a.has("rig"))
    runtime_error(reader.path() +
                  ": the recording stores no rig (meta rig_yaml is empty); give one with --rig");
  for (const auto& t : replay.frame_times())
    if (t) {
      f.origin_ns = *t;  // the first readable frame's pair time
      break;
    }
  if (max_pairs) {
    const std::size_t start = replay.start_frame();
    check(replay.set_end_frame(
        start + std::min<std::size_t>(static_cast<std::size_t>(max_pairs), replay.frame_count())));
    f.range_in_source = true;
  }
  f.total_pairs = replay.end_frame() - replay.start_frame();
  return f;
}

// A source other than a recording or a simulated flight: an MCAP file, a EuRoC folder, a frame index.
SourceFacts other_source_facts(FrameSource& source, const std::string& src, long long max_pairs) {
  SourceFacts f;
  // An MCAP file from augrig export: read front to back, with the rig in its metadata.
  if (const auto meta = source.metadata(); meta.count("rig_yaml"))
    f.rig = unwrap(parse_rig(meta.at("rig_yaml"), src + " (metadata augrig_recording, rig_yaml)"));
  // A EuRoC folder: a range of its pairs, counted and timed from the folder's first.
  if (source.capabilities().ranged) {
    f.origin_ns = source.origin_t_ns();
    f.euroc_start = source.range_start();
    if (max_pairs) {
      check(source.set_range_end(
          source.range_start() +
          std::min<std::size_t>(static_cast<std::size_t>(max_pairs), source.pair_count())));
      f.range_in_source = true;
    }
  }
  f.total_pairs = source.pair_count();
  return f;
}

SourceFacts source_facts(OpenedSource& opened, const ParsedArgs& a, const std::string& src, bool is_sim,
                         long long max_pairs, std::ostream& err) {
  if (is_sim) {
    SourceFacts f;
    f.rig = opened.sim->scenario.rig;
    f.total_pairs = opened.sources.front()->pair_count();
    return f;
  }
  if (opened.replay) return recording_facts(*opened.replay, a, max_pairs, err);
  return other_source_facts(*opened.sources.front(), src, max_pairs);
}

// The pipeline's rig, models, poses, boom and look (the outputs and callbacks are added later).
PipelineParts evaluation_parts(const ParsedArgs& a, const Rig& rig, const OpenedSource& opened,
                               const SourceFacts& facts, const SourceKind& kind, const EvaluateFlags& f,
                               bool scenario_boom) {
  PipelineParts parts;
  parts.rig = rig;
  parts.models = unwrap(load_rig_models(rig));
  parts.source_info = opened;
  PoseSources ps;
  ps.scene_path = a.get("scene", "");
  ps.poses_csv_path = a.get("poses", "");
  ps.pose_tolerance_ns = parse_pose_tolerance(a);
  ps.recorded = !kind.sim;  // a recording's (EuRoC folders have none: their frames are counted)
  ps.recorded_rig = facts.rig;
  ps.sim = opened.sim.get();
  parts.poses = unwrap(choose_poses(ps, rig, parts.models.receptacle_m)).provider;
  if (scenario_boom) parts.poses = std::make_unique<ScenarioBoomPoses>(std::move(parts.poses));
  // A frame without a pose (not in the poses CSV, no recorded scene) is counted, not guessed.
  parts.skip_frames_without_pose = !kind.sim && !a.has("scene");
  if (a.has("boom") && !scenario_boom) parts.boom = parse_boom_arg(a.get("boom"));
  // The physical boom: the augmenter's plain look (AugmentOptions' default) only for the masks,
  // depth, classes and statistics; its images are not scored.
  if (!f.physical) apply_look_arg(a, rig, parts.augment);
  return parts;
}

// Each evaluated pair: scored, its CSV rows, its point on the plots, its images.
class PairScorer {
 public:
  PairScorer(const EvaluateFlags& flags, eval::StereoEvaluator& evaluator, SourceFacts& facts,
             fs::path out_dir)
      : flags_(flags), evaluator_(evaluator), facts_(facts), out_dir_(std::move(out_dir)) {}

  // The CSV writers, with --out.
  std::unique_ptr<eval::EvaluationCsvWriter> csv;
  std::unique_ptr<eval::EvaluationSumsWriter> sums;
  eval::RunEvaluation run;
  std::vector<eval::EvaluationPoint> points;

  Status on_pair(const StereoFrame& raw, const StereoResult& result) {
    if (seen_++ == 0 && !facts_.origin_ns) facts_.origin_ns = result.stats.t_ns;
    const std::uint64_t index = source_index(raw);
    // Selected and imaged by the source's index, not by the count in this run: a part of the run
    // picks the frames the whole run picks in its range.
    const auto every = static_cast<std::uint64_t>(flags_.every);
    if (index % every != 0) return {};
    eval::EvaluationImages images;
    const bool want_images =
        flags_.images_every && index % (every * static_cast<std::uint64_t>(flags_.images_every)) == 0;
    auto fe = evaluator_.evaluate(raw, scored(result), want_images ? &images : nullptr);
    if (!fe) return make_error("pair ", raw.pair_sequence, ": ", fe.error().message);
    const double t_s = ns_to_s(result.stats.t_ns - *facts_.origin_ns);
    if (csv)
      if (Status s = csv->add(index, t_s, result.stats, *fe); !s) return s;
    if (sums)
      if (Status s =
              sums->add({index, t_s, result.stats.occluded_pct_left, result.stats.occluded_pct_right, *fe});
          !s)
        return s;
    points.push_back(eval::evaluation_point(t_s, result.stats, *fe));
    if (want_images) write_images(index, images, fe->matched);
    run.add(*fe);
    return {};
  }

 private:
  // The frame's index in the source: its position in the recording or folder, else the count of
  // augmented pairs (a frame index or simulated flight).
  std::uint64_t source_index(const StereoFrame& raw) const {
    if (const std::optional<SourcePosition> at =
            raw.left.attachment ? raw.left.attachment->position() : std::nullopt)
      return at->index;
    if (facts_.euroc_start) return *facts_.euroc_start + raw.left.sequence;
    return seen_ - 1;
  }

  // --look physical: the augmenter's result with no augmented image, so that the evaluator's
  // augmented pair (whole_augmented()) is the source's frames, the boom in the scene.
  const StereoResult& scored(const StereoResult& result) {
    if (!flags_.physical) return result;
    frames_as_augmented_ = result;
    for (ViewResult* v : {&frames_as_augmented_.left, &frames_as_augmented_.right}) {
      v->augmented = Image();
      v->augmented_box = PixelBox{};
    }
    return frames_as_augmented_;
  }

  void write_images(std::uint64_t index, const eval::EvaluationImages& images,
                    const cv::Rect& matched) const {
    char stem[32];
    std::snprintf(stem, sizeof stem, "%06llu", static_cast<unsigned long long>(index));
    const fs::path d = out_dir_ / "disparity";
    write_disparity_png(d / (std::string(stem) + "_true.png"), images.true_disparity);
    write_disparity_png(d / (std::string(stem) + "_raw.png"), images.raw_disparity);
    write_disparity_png(d / (std::string(stem) + "_augmented.png"), images.aug_disparity);
    write_disparity_view(d / (std::string(stem) + "_view.png"), images, matched);
  }

  const EvaluateFlags& flags_;
  eval::StereoEvaluator& evaluator_;
  SourceFacts& facts_;  // origin_ns: set by the first pair where the source has none
  fs::path out_dir_;
  std::uint64_t seen_ = 0;  // augmented pairs: the frame index of a frame index or simulated flight
  StereoResult frames_as_augmented_;
};

// The run's first line: the source, rig, poses, matcher, selection and look.
void print_run_header(std::ostream& out, const std::string& uri, const Rig& rig, const PoseProvider& poses,
                      const EvaluateFlags& f) {
  const eval::MatcherParams& m = f.eo.matcher;
  out << "evaluate: " << uri << "; rig " << rig.source << "; poses from " << poses.describe() << "; "
      << (m.algorithm == "bm" ? "StereoBM" : "StereoSGBM " + m.mode) << ", disparities " << m.min_disparity
      << ".." << m.min_disparity + m.num_disparities - 1 << ", block " << m.block_size << "; "
      << (f.every == 1 ? std::string("every frame") : "every " + std::to_string(f.every) + "th frame") << "; "
      << look_text(f.look) << "\n";
}

// The table, the timing line and, with --out, evaluation.txt and the plot.
void report_evaluation(const ParsedArgs& a, const std::string& source, const EvaluateFlags& f,
                       const PairScorer& scorer, const PipelineReport& r, double wall_s,
                       const fs::path& out_dir, std::ostream& out) {
  const eval::RunEvaluation& run = scorer.run;
  // The source as given (a physical boom's boom=physical is said by the look), the look on the
  // title line: the rest of the table is what a campaign's merge rebuilds from the sums.
  const std::string table = eval::format_evaluation_table(
      run, "Stereo evaluation: " + source + "; " + look_text(f.look), f.eo.matcher,
      f.look == "physical" ? "the boom in the scene" : "the boom drawn in");
  out << "\n" << table;
  const double per = run.frames ? 1.0 / static_cast<double>(run.frames) : 0.0;
  out << "\nEvaluated " << run.frames << " of " << r.pairs << " augmented stereo frame(s) in "
      << fmt_ms(wall_s) << " s (" << fmt_ms(run.frames / std::max(wall_s, 1e-9))
      << " evaluated frames/s; per frame: prepare " << fmt_ms(run.prepare_ms * per) << " ms, match "
      << fmt_ms(run.match_ms * per) << " ms, truth and scores " << fmt_ms(run.score_ms * per) << " ms)\n";
  if (r.skipped_no_pose)
    out << r.skipped_no_pose << " frame(s) had no recorded scene and were not evaluated\n";
  if (!a.has("out")) return;
  std::ofstream t(out_dir / "evaluation.txt", std::ios::binary);
  t << table;
  if (!t) runtime_error((out_dir / "evaluation.txt").string() + ": cannot write the table");
  out << "Wrote " << (out_dir / "evaluation.txt").string()
      << ", evaluation.csv, evaluation_sums.csv and stats.csv";
  if (!a.has("no-plot") && !scorer.points.empty()) {
    check(eval::plot_evaluation(scorer.points, (out_dir / "evaluation.png").string(),
                                "Stereo evaluation: " + source + ", look " + f.look));
    out << ", evaluation.png";
  }
  if (f.images_every) out << " and the disparity images of 1 in " << f.images_every << " evaluated frames";
  out << "\n";
}

int evaluate_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  std::vector<std::string> pos;
  const ParsedArgs a = parse_with_positionals(args, evaluate_specs(), {"SOURCE"}, pos);
  if (a.help) {
    print_evaluate_help(out);
    return kExitOk;
  }
  const EvaluateFlags f = parse_evaluate_flags(a);

  // The source: a simulated flight, a frame index, a EuRoC folder or a recording.
  std::string src = pos[0];
  const SourceKind kind = classify_source(src);
  const std::string start = start_params(a, kind);  // the start parameters of a recording or dataset
  if (a.has("pair-tolerance-ns") && !kind.euroc) usage_error("--pair-tolerance-ns is for EuRoC folders");
  if (f.physical) apply_physical_look(a, kind, src);
  // --boom scenario (--look physical's boom): the simulated flight's own, as its truth gives it.
  const bool scenario_boom = f.physical || a.get("boom") == "scenario";
  if (scenario_boom && (!kind.sim || a.has("scene") || a.has("poses")))
    usage_error(
        "--boom scenario: only a simulated flight (sim://SCENARIO) with its own poses has the "
        "scenario's boom");
  const std::string uri = source_uri(a, src, kind, start);
  OpenedSource opened = unwrap(open_sources(uri));
  SourceFacts facts = source_facts(opened, a, src, kind.sim, f.max_pairs, err);
  const Rig rig = a.has("rig") ? load_rig_arg(a.get("rig")) : facts.rig ? *facts.rig : Rig::paper_default();
  if (rig.cameras.size() != 2)
    runtime_error(rig.source + ": the rig needs 2 cameras, has " + std::to_string(rig.cameras.size()));
  auto evaluator = unwrap(eval::StereoEvaluator::create(rig, f.eo));

  PipelineParts parts = evaluation_parts(a, rig, opened, facts, kind, f, scenario_boom);
  const fs::path out_dir = a.get("out");
  PairScorer scorer(f, *evaluator, facts, out_dir);
  if (a.has("out")) {
    make_dirs(out_dir);
    parts.stats_csv = unwrap(StatsCsvWriter::create(out_dir / "stats.csv"));
    scorer.csv = unwrap(eval::EvaluationCsvWriter::create(out_dir / "evaluation.csv"));
    scorer.sums = unwrap(eval::EvaluationSumsWriter::create(out_dir / "evaluation_sums.csv"));
    if (f.images_every) make_dirs(out_dir / "disparity");
  }
  parts.on_pair = [&scorer](const StereoFrame& raw, const StereoResult& result, const SceneState&,
                            const FramePoses&) -> Status { return scorer.on_pair(raw, result); };
  parts.source = unwrap(start_stereo(std::move(opened)));
  parts.stop_flag = install_stop_signals();
  if (!facts.range_in_source) parts.max_pairs = static_cast<std::uint64_t>(f.max_pairs);
  parts.progress_total =
      parts.max_pairs ? std::min<std::uint64_t>(facts.total_pairs, parts.max_pairs) : facts.total_pairs;
  parts.on_problem = [&err](const Error& e) { err << "augrig evaluate: " << user_message(e) << "\n"; };
  print_run_header(out, uri, rig, *parts.poses, f);
  const auto wall0 = Clock::now();
  Pipeline pipeline(std::move(parts));
  const PipelineReport r = run_pipeline(pipeline, false, a.has("out") ? out_dir.string() : ".", out, err);
  const double wall_s = ms_since(wall0) / 1000.0;

  report_evaluation(a, pos[0], f, scorer, r, wall_s, out_dir, out);
  if (r.failed_pairs)
    runtime_error(std::to_string(r.failed_pairs) + " stereo frame(s) could not be augmented (above)");
  // Damage exits 1 as in `replay` (an incomplete recording too), unless --allow-damaged.
  if (const recorder::ReplaySource* replay = pipeline.parts().source_info.replay)
    recording_damage(a, "evaluate", !replay->reader().problems().empty(), replay->damaged_frames(),
                     "evaluated", err);
  if (r.stopped_by_signal) return kExitRuntime;
  return kExitOk;
}

}  // namespace

int cmd_evaluate(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("evaluate", err, [&] { return evaluate_command(args, out, err); });
}

}  // namespace augrig::app
