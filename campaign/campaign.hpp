// campaign: a flight-test campaign re-augmented and evaluated on a cluster (docs/CAMPAIGN.md).
// A campaign file names the flights (recordings, EuRoC folders, MCAP files), the variants (boom,
// rig, scene, evaluation settings) and the output folder. plan() cuts every flight into shards
// by time and makes one task per shard and variant: an ordinary `augrig evaluate` or `augrig
// replay` command line over the shard's frames. The manifest (manifest.yaml in the output folder)
// holds them; Slurm runs them as an array job (campaign/slurm.hpp), each task through
// campaign/task.hpp, and campaign/merge.hpp joins the shards' outputs into the reports.
//
// No stage of those commands carries state from one frame to the next that a shard would miss:
// poses are recorded or given per flight (augrig nav fuses a whole flight once, before), a
// scripted boom's clock and the evaluation cadence (--every) count from the flight's first frame.
// So shards need no overlap, and merged results equal those of one unsharded run.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/expected.hpp"

namespace augrig::campaign {

enum class FlightKind { kRecording, kEuroc, kMcap };
const char* to_string(FlightKind k);

struct FlightSpec {
  std::string name;            // unique in the campaign: [A-Za-z0-9._-]
  std::filesystem::path path;  // absolute
  FlightKind kind = FlightKind::kRecording;
  std::filesystem::path poses;  // absolute; empty: the source's own (recorded) poses
};

// One way of augmenting every flight. Empty strings: the command's default (the source's rig,
// boom and poses).
struct VariantSpec {
  std::string name;                             // unique: [A-Za-z0-9._-]
  std::string rig, boom, scene, receiver_draw;  // paths absolute; boom: track | fixed:.. | script:FILE
  // With `evaluate`, each task is `augrig evaluate` (stereo matching scored per frame); without it,
  // `augrig replay` (the occlusion statistics only).
  bool evaluate = false;
  std::string matcher;  // absolute path; empty: evaluate's default
  int every = 1;        // evaluate every K-th frame of the flight
  std::optional<int> context_px;
  bool full_frame = false;
  // exports: [mcap]: each shard's re-augmented frames as an MCAP file (--sink mcap:), joined per
  // flight by the merge (recorder::merge_mcap) into report/VARIANT/FLIGHT/flight.mcap.
  bool export_mcap = false;
  // exports: [euroc]: each shard's as a EuRoC folder on the recording's clock with its nav inputs
  // (--sink euroc:...,nav), joined per flight (recorder::merge_euroc) into report/VARIANT/FLIGHT/euroc.
  bool export_euroc = false;
  // exports: [recording]: each shard's re-augmented frames recorded (--record {out}/recording),
  // joined per flight (recorder::merge_recordings, with the flight's nav inputs) into
  // report/VARIANT/FLIGHT/recording.
  bool export_recording = false;
  // look: plain | camera (replay's --look; empty: its default). Evaluations always use plain. The
  // camera look's estimates start over at each shard's first frame, as a restarted run's would:
  // its augmented images are a camera's, but not bit for bit those of one unsharded run.
  std::string look;
};

struct SlurmSpec {
  std::string partition, account;
  int cpus_per_task = 2;
  double time_safety = 3.0;        // the time limit is this times the measured cost, plus the start-up
  int max_array_size = 1001;       // Slurm's MaxArraySize: array indices stay below it
  int max_running = 0;             // "%N" on the array: at most N tasks at once (0: no limit)
  std::vector<std::string> extra;  // more #SBATCH lines, e.g. "--qos=long"
};

struct CampaignSpec {
  std::filesystem::path file;  // the campaign file, absolute
  std::string name;
  std::filesystem::path out;  // absolute
  std::vector<FlightSpec> flights;
  std::vector<VariantSpec> variants;
  // Shard length: fixed in recorded seconds, or chosen so that a task takes about task_minutes.
  std::optional<double> shard_seconds;
  double task_minutes = 30;
  SlurmSpec slurm;
};

// Reads a campaign file; paths in it are relative to its folder. Errors name file:line:col, the key
// and what was expected; flights that do not exist or are not a recording, EuRoC folder or MCAP file
// are errors here, not in a task hours later.
Expected<CampaignSpec> load_campaign(const std::filesystem::path& file);
Expected<CampaignSpec> parse_campaign(const std::string& yaml_text, const std::filesystem::path& file);

// A flight's stereo frames in source order: each pair's time (ns; nullopt where unreadable).
struct FlightFrames {
  std::vector<std::optional<std::int64_t>> t_ns;
  bool splittable = true;  // MCAP files are read front to back: one shard
  // A flight read whole (MCAP): its stereo frames, from the file's statistics (0: not known). Its
  // one shard counts them, so that its time limit and its frames left out do.
  std::size_t whole_frames = 0;
  // Both cameras' image sizes and formats ("Mono8 1280x960 + Mono8 1280x960"; "" unknown): a
  // variant's cost is measured once per kind of flight.
  std::string images;
};
Expected<FlightFrames> read_flight_frames(const FlightSpec& flight);

// A flight's recorded time as shards count it: seconds after its first readable frame, never
// going back. A clock that steps back (a host clock set, a GPS time jump) or repeats a time counts
// the flight's typical frame interval there instead, so that shards stay as long as asked for; an
// unreadable frame takes its predecessor's time.
struct FlightClock {
  std::vector<double> elapsed_s;  // per frame
  std::size_t steps_back = 0;     // frames whose time is not after the frame before
  double largest_step_back_s = 0;
  std::size_t first_step_back_frame = 0;
};
FlightClock flight_clock(const FlightFrames& f);

// A range of a flight's frames, [from_frame, from_frame + frames).
struct Shard {
  std::size_t index = 0;  // within the flight
  std::size_t from_frame = 0, frames = 0;
  double t_from_s = 0, t_to_s = 0;  // seconds after the flight's first frame
};
// Cuts a flight into shards of `seconds` of recorded time (flight_clock; the last may be shorter); with
// `align` > 1, every shard starts at a multiple of it (the evaluation cadence). A flight that
// cannot be split, or is shorter, is one shard.
std::vector<Shard> split_flight(const FlightFrames& f, double seconds, std::size_t align = 1);

// The measured cost of a variant's task: start-up and per frame, seconds; peak memory, bytes.
struct TaskCost {
  double startup_s = 0, per_frame_s = 0;
  std::int64_t max_rss_bytes = 0;
  std::string measured_on;  // "flight F, frames A..B, host H"
};

struct Task {
  std::size_t id = 0;  // the array index (0-based, in the manifest's order)
  std::string flight, variant;
  Shard shard;
  std::filesystem::path out;      // the shard's output folder, absolute
  std::vector<std::string> argv;  // the augrig command, without the program and without --out
};

// In a task's argv, kTaskOut stands for the folder the task writes (run_task puts it in); a shard's
// MCAP export is kTaskOut/kShardMcap, its EuRoC export kTaskOut/kShardEuroc.
inline constexpr const char* kTaskOut = "{out}";
inline constexpr const char* kShardMcap = "flight.mcap";
// A shard's EuRoC export: kTaskOut/kShardEuroc, its sink's argument kShardEurocSink.
inline constexpr const char* kShardEuroc = "euroc";
inline constexpr const char* kShardEurocSink = "euroc:{out}/euroc,nav,no-plot";
// A shard's re-augmented recording: kTaskOut/kShardRecording.
inline constexpr const char* kShardRecording = "recording";

struct Manifest {
  std::filesystem::path file;  // manifest.yaml, absolute
  std::string name;
  std::filesystem::path campaign_file, out, augrig;  // augrig: the binary tasks run
  std::string planned_at;
  double heartbeat_s = 10;  // a task touches its heartbeat this often; 3x stale: stopped
  SlurmSpec slurm;          // as planned: resume submits with the same settings
  std::vector<std::pair<std::string, TaskCost>> costs;  // per variant
  std::vector<Task> tasks;
  const TaskCost* cost_of(const std::string& variant) const;
};

// The command line a task runs for `shard` of `flight` under `variant` (without --out).
std::vector<std::string> task_command(const FlightSpec& flight, const VariantSpec& variant,
                                      const Shard& shard, bool whole_flight);

// The tasks of a campaign, variants then flights then shards: each (flight, variant) cut by the
// campaign's shard length (or the length a task of `task_minutes` covers at the variant's
// measured cost), aligned to the variant's evaluation cadence. `frames[i]` are flight i's.
std::vector<Task> plan_tasks(const CampaignSpec& spec, const std::vector<FlightFrames>& frames,
                             const std::vector<std::pair<std::string, TaskCost>>& costs);

// Where a shard's outputs go: OUT/shards/VARIANT/FLIGHT/NNNN.
std::filesystem::path shard_dir(const std::filesystem::path& out, const std::string& variant,
                                const std::string& flight, std::size_t shard_index);

Status write_manifest(const Manifest& m);
Expected<Manifest> load_manifest(const std::filesystem::path& file);

// The wall clock: seconds since the epoch (what file times are aged against), and as ISO 8601 UTC.
double wall_clock_s();
std::string utc_now_iso();

// `seconds` as Slurm's time limit, D-HH:MM:SS rounded up to whole minutes.
std::string slurm_time(double seconds);

}  // namespace augrig::campaign
