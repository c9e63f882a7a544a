// What the augrig commands share (internal to app/): how a command fails (CommandError, exit codes
// 1 and 2), turning library errors into user messages, flag values used by several commands, GL
// context creation and the common outputs (PNG frames, stats.csv).
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <ostream>
#include <string>

#include <Eigen/Core>

#include "app/commands.hpp"
#include "core/expected.hpp"
#include "core/frame.hpp"
#include "pipeline/boom_stage.hpp"
#include "pipeline/outputs.hpp"
#include "pipeline/pipeline.hpp"
#include "recorder/record.hpp"
#include "render/augmenter.hpp"
#include "render/boom_control.hpp"
#include "render/gl_context.hpp"
#include "render/models.hpp"
#include "render/rig.hpp"
#include "render/stats.hpp"

namespace augrig::pipeline {}
namespace augrig::recorder {
class RecordingReader;
class Recorder;
struct RecordingInfo;
}  // namespace augrig::recorder

namespace augrig::app {

// The commands configure the runtime: its names are theirs.
using namespace augrig::pipeline;

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t0);
std::string fmt_ms(double ms);

// A command failed for a reason the user can fix in an input (exit 1) or in the flags (exit 2).
struct CommandError {
  int code;
  std::string message;
};
[[noreturn]] void runtime_error(const std::string& what);
[[noreturn]] void usage_error(const std::string& what);

// Library errors read "module::function(): file:line: ..."; the CLI prints its own prefix instead,
// so the user sees "augrig augment: file:line: ...".
std::string user_message(const Error& e);

template <typename T>
T unwrap(Expected<T> e) {
  if (!e) runtime_error(user_message(e.error()));
  return std::move(e).value();
}
void check(const Status& s);

// Parses a command's flags; prints its help and returns nullopt-like `help = true` args for --help.
ParsedArgs parse_or_usage(const std::vector<std::string>& args, const std::vector<OptionSpec>& specs);

// ---- Shared flag values ---------------------------------------------------------------------------

// "default" is the seed paper's rig; anything else a rig file.
Rig load_rig_arg(const std::string& value);
ReceiverDraw parse_receiver_draw(const std::string& v);
PixelFormat parse_bayer(const std::string& v);
// A whole number in [lo, hi] for flag `flag`, else a usage error.
long long parse_integer(const std::string& flag, const std::string& v, long long lo, long long hi);
double parse_real(const std::string& flag, const std::string& v);

// "NAME=VALUE,..." (pipeline::parse_named_list), a usage error saying `what` otherwise.
std::vector<std::pair<std::string, std::string>> parse_named_list_arg(const std::string& v,
                                                                      const std::string& what);

// A display to open the window on (DISPLAY set and not empty).
bool display_present();
// --pose-tolerance-ms MS (default 0: exactly) as nanoseconds; milliseconds in [0, 1e6].
TimestampNs parse_pose_tolerance(const ParsedArgs& a);
// --screenshot-at N (0 when not given).
std::uint64_t parse_screenshot_at(const ParsedArgs& a);

// --boom: track, fixed:EL_DEG,AZ_DEG,EXT_M or script:FILE.csv (pipeline/boom_stage.hpp).
BoomArg parse_boom_arg(const std::string& v);

// ---- The flags the augmenting commands share (run, replay, augment, evaluate, demo) ------------
// One name, one value syntax and one meaning each; `default_text` is the command's own default.
OptionSpec rig_option(const std::string& default_text, bool required = false);
OptionSpec scene_option(const std::string& default_text, bool folder = false);  // folder: SCENE.yaml|DIR
OptionSpec poses_option(const std::string& extra = "");
OptionSpec pose_tolerance_option();
// --allow-damaged (replay, evaluate): input frames that cannot be read (a damaged blob, a recording
// cut short) are reported and left out of the outputs, and the command still exits 0. Campaign
// tasks pass it: a shard of a damaged recording is done, with its missing frames counted, rather
// than failed on every run.
OptionSpec allow_damaged_option();
// Damaged input (`what`): an error (exit 1); with --allow-damaged, a line on `err` and the command
// goes on.
void input_damage(const ParsedArgs& a, const std::string& command, const std::string& what,
                  std::ostream& err);
// A replayed recording's damage, after the outputs, as input_damage(): the recording is incomplete
// (its reader listed problems) and/or `unreadable` frames could not be read; `done` says what
// became of the others ("replayed", "evaluated").
void recording_damage(const ParsedArgs& a, const std::string& command, bool incomplete,
                      std::uint64_t unreadable, const std::string& done, std::ostream& err);
OptionSpec boom_option(const std::string& default_text);
OptionSpec receiver_draw_option();
// --look plain|camera (render/camera_look.hpp) into `options`, with the rig's per-camera look keys.
OptionSpec look_option();
void apply_look_arg(const ParsedArgs& a, const Rig& rig, AugmentOptions& options);
// --sink SCHEME:ARG, repeatable (pipeline/sinks/registry.hpp: video:FILE.mp4, tum:FILE.txt): each
// made for `parts.rig` and added to `parts.sinks`; a bad one is a usage error naming it.
OptionSpec sink_option();
void apply_sink_args(const ParsedArgs& a, pipeline::PipelineParts& parts, const std::string& replayed = {});

// replay's core (cmd_recording.cpp) for a command that replays into outputs of its own (export
// --reaugment): `input` a recording, an MCAP file or a EuRoC folder, `a` replay's options;
// `add_sinks` is called once the replay's rig is known, to add the caller's sinks to `parts`.
using AddSinks = std::function<void(pipeline::PipelineParts& parts)>;
int replay_into(const std::string& input, const ParsedArgs& a, const AddSinks& add_sinks, std::ostream& out,
                std::ostream& err);

std::unique_ptr<GlContext> make_gl_context();
void make_dirs(const fs::path& dir);

// ---- Outputs --------------------------------------------------------------------------------------

void write_png(const fs::path& path, const Image& image);
// Everything `augment` and `demo` write for one stereo frame (docs/CLI.md gives the layout); `raw`
// is the frame `r` was made from (its augmented images may be the changed boxes only).
void write_frame_outputs(const fs::path& out, const FrameNames& n, const StereoFrame& raw,
                         const StereoResult& r);

// stats.csv, one row per stereo frame, flushed per row so a failed run keeps what it counted.
class StatsCsv {
 public:
  explicit StatsCsv(const fs::path& path);
  void add(const OcclusionStats& s);

 private:
  std::unique_ptr<StatsCsvWriter> writer_;
};

// ---- Positional arguments and recordings ------------------------------------------------------

// Parses the flags of `args` and exactly the positionals `names` (a usage error names what is
// missing or extra); `positionals` gets them in order.
ParsedArgs parse_with_positionals(const std::vector<std::string>& args, const std::vector<OptionSpec>& specs,
                                  const std::vector<std::string>& names,
                                  std::vector<std::string>& positionals);
// A new recording in `dir` (--record), or a runtime error; one already there is replaced only with
// `overwrite` (--overwrite), and the error says so.
std::unique_ptr<recorder::Recorder> create_recorder(const std::string& dir,
                                                    const recorder::RecordingInfo& info, bool overwrite);
// Opens a recording, or fails the command naming it.
std::unique_ptr<recorder::RecordingReader> open_recording(const std::string& dir);
// A problem of the recording as a whole (RecordingReader::problems()), naming its file.
std::string recording_problem(const recorder::RecordingReader& reader, const std::string& problem);

// SIGINT and SIGTERM raise the returned flag (a pipeline's stop_flag): the run stops cleanly.
std::atomic<bool>* install_stop_signals();

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

}  // namespace augrig::app
