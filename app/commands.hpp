// The `augrig` command line: a small hand-written argument parser, image file I/O in augrig's
// pixel formats, and the commands (augment, demo). docs/CLI.md documents every command and flag.
// Exit codes: 0 ok, 1 runtime error (bad input content, GL failure...), 2 usage error.
#pragma once

#include <iosfwd>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/expected.hpp"
#include "core/image.hpp"

namespace augrig::app {

enum ExitCode : int { kExitOk = 0, kExitRuntime = 1, kExitUsage = 2 };

// ---- Argument parsing -------------------------------------------------------------------------

enum class ArgKind {
  kFlag,           // --name
  kValue,          // --name VALUE or --name=VALUE
  kOptionalValue,  // --name or --name=VALUE (never takes the next argument)
};

// --ground-truth means the same in every command that writes per-frame files (augment, demo,
// replay, run): pipeline::write_ground_truth() beside each frame's images.
inline constexpr const char* kGroundTruthHelp =
    "also write each written frame's ground truth: receiver depth (.npy metres, 16-bit PNG mm), where each "
    "left receiver pixel lies in the right image (.npy), the stereo classes (docs/GROUND_TRUTH.md)";

struct OptionSpec {
  std::string name;  // without the leading "--"
  ArgKind kind = ArgKind::kValue;
  std::string metavar;  // shown in the help ("RIG.yaml")
  std::string help;
  bool required = false;
  bool repeatable = false;  // may be given more than once (ParsedArgs::all)
};

struct ParsedArgs {
  std::map<std::string, std::string> values;  // flags map to "" (kOptionalValue without '=' too)
  bool help = false;
  bool has(const std::string& name) const { return values.count(name) != 0; }
  // Every value of a repeatable option, in the order given.
  std::vector<std::string> all(const std::string& name) const;
  std::string get(const std::string& name, const std::string& fallback = "") const {
    const auto it = values.find(name);
    return it == values.end() ? fallback : it->second;
  }
};

// Parses long options. Errors (unknown flag, missing value, missing required flag, stray argument)
// come back as one-line messages; `--help`/`-h` short-circuits the required-flag check.
Expected<ParsedArgs> parse_args(const std::vector<std::string>& args, const std::vector<OptionSpec>& specs);
// "Usage: ..." plus one line per option.
std::string format_help(const std::string& usage, const std::string& summary,
                        const std::vector<OptionSpec>& specs);

// ---- Images -----------------------------------------------------------------------------------

// Reads an image file as augrig's formats: forwards to augrig::read_image_file (render/image_file.hpp).
Expected<Image> read_image_file(const std::string& path, std::optional<PixelFormat> bayer = std::nullopt);
// Writes an image losslessly (PNG): RGB(A) is converted to OpenCV's BGR(A) order, Mono8 and Bayer are
// written as 8-bit gray. Creates the parent folder.
Status write_image_file(const std::string& path, const Image& image, int png_compression = 1);

// ---- Commands ---------------------------------------------------------------------------------

// `augrig <args...>`: dispatches to a command; prints errors as "augrig <command>: <what>" to `err`.
int run_cli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int cmd_augment(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int cmd_demo(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int cmd_sim(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int cmd_nav(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int cmd_check(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int cmd_replay(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int cmd_export(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int cmd_rig(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int cmd_evaluate(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int cmd_cameras(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int cmd_run(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int cmd_campaign(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

}  // namespace augrig::app
