#include "campaign/campaign.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <numeric>
#include <set>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "core/yaml_reader.hpp"
#include "recorder/euroc_source.hpp"
#include "recorder/mcap_source.hpp"
#include "recorder/reader.hpp"

namespace augrig::campaign {

namespace fs = std::filesystem;
using namespace yaml;  // located errors and key checks (core/yaml_reader.hpp)

const char* to_string(FlightKind k) {
  switch (k) {
    case FlightKind::kRecording:
      return "recording";
    case FlightKind::kEuroc:
      return "EuRoC folder";
    case FlightKind::kMcap:
      return "MCAP file";
  }
  return "?";
}

namespace {

constexpr const char* kLoad = "campaign::load(): ";

bool is_name(const std::string& s) {
  return !s.empty() && s.size() <= 64 && s != "." && s != ".." && std::all_of(s.begin(), s.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.';
  });
}

std::string name_value(const Context& c, const YAML::Node& n, const std::string& key) {
  const std::string v = to_string_value(c, n, key, "a name of letters, digits, '.', '_' and '-'");
  if (!is_name(v))
    fail(c, n, key, "expected a name of letters, digits, '.', '_' and '-' (at most 64), " + got(n));
  return v;
}

// A path in the campaign file, relative to the file's folder.
fs::path path_value(const Context& c, const YAML::Node& n, const std::string& key, const fs::path& base,
                    const std::string& what, bool must_exist) {
  const std::string v = to_string_value(c, n, key, what);
  if (v.empty()) fail(c, n, key, "expected " + what + ", got an empty string");
  const fs::path p = fs::weakly_canonical(fs::path(v).is_absolute() ? fs::path(v) : base / v);
  if (must_exist && !fs::exists(p))
    fail(c, n, key, "expected " + what + ", but " + p.string() + " does not exist");
  return p;
}

FlightKind kind_of(const Context& c, const YAML::Node& n, const std::string& key, const fs::path& p) {
  if (fs::is_regular_file(p) && recorder::is_mcap_path(p.string())) return FlightKind::kMcap;
  if (fs::is_regular_file(p / "recording.sqlite")) return FlightKind::kRecording;
  if (fs::is_directory(p / "mav0") || (p.filename() == "mav0" && fs::is_directory(p)))
    return FlightKind::kEuroc;
  fail(c, n, key,
       "expected a recording (a folder with recording.sqlite), a EuRoC/ASL folder (with mav0/) or an MCAP "
       "file, "
       "but " +
           p.string() + " is none of them");
}

FlightSpec parse_flight(const Context& c, const YAML::Node& n, const std::string& key, const fs::path& base) {
  FlightSpec f;
  const YAML::Node path_node = n.IsMap() ? require(c, n, key, "path", "the flight's path") : n;
  const std::string path_key = n.IsMap() ? join_key(key, "path") : key;
  if (n.IsMap()) check_keys(c, n, key, {"path", "name", "poses"});
  f.path = path_value(c, path_node, path_key, base, "a recording, EuRoC folder or MCAP file", true);
  f.kind = kind_of(c, path_node, path_key, f.path);
  f.name = f.path.filename() == "mav0" ? f.path.parent_path().filename().string() : f.path.stem().string();
  if (n.IsMap() && n["name"])
    f.name = name_value(c, n["name"], join_key(key, "name"));
  else if (!is_name(f.name))
    fail(c, path_node, path_key,
         "the folder's name '" + f.name +
             "' cannot name the flight's outputs: give `name:` (letters, digits, "
             "'.', '_', '-')");
  if (n.IsMap() && n["poses"])
    f.poses = path_value(c, n["poses"], join_key(key, "poses"), base, "a poses CSV (augrig nav's)", true);
  return f;
}

VariantSpec parse_variant(const Context& c, const YAML::Node& n, const std::string& key,
                          const fs::path& base) {
  expect_map(c, n, key, "a variant (a map with name and what it changes)");
  check_keys(c, n, key, {"name", "rig", "boom", "scene", "receiver_draw", "look", "evaluate", "exports"});
  VariantSpec v;
  v.name = name_value(c, require(c, n, key, "name", "the variant's name"), join_key(key, "name"));
  if (n["rig"]) {
    const std::string r = to_string_value(c, n["rig"], join_key(key, "rig"), "a rig file or 'default'");
    v.rig =
        r == "default" ? r : path_value(c, n["rig"], join_key(key, "rig"), base, "a rig file", true).string();
  }
  if (n["boom"]) {
    const std::string b =
        to_string_value(c, n["boom"], join_key(key, "boom"), "track, fixed:EL,AZ,EXT or script:FILE");
    if (b.rfind("script:", 0) == 0) {
      const fs::path s = fs::path(b.substr(7)).is_absolute() ? fs::path(b.substr(7)) : base / b.substr(7);
      if (!fs::is_regular_file(s))
        fail(c, n["boom"], join_key(key, "boom"), "the boom script " + s.string() + " does not exist");
      v.boom = "script:" + fs::weakly_canonical(s).string();
    } else if (b == "track" || b.rfind("fixed:", 0) == 0) {
      v.boom = b;
    } else {
      fail(c, n["boom"], join_key(key, "boom"),
           "expected track, fixed:EL_DEG,AZ_DEG,EXT_M or script:FILE.csv, " + got(n["boom"]));
    }
  }
  if (n["scene"])
    v.scene = path_value(c, n["scene"], join_key(key, "scene"), base, "a scene file", true).string();
  if (n["receiver_draw"]) {
    v.receiver_draw = to_string_value(c, n["receiver_draw"], join_key(key, "receiver_draw"),
                                      "mask, wireframe or translucent");
    if (v.receiver_draw != "mask" && v.receiver_draw != "wireframe" && v.receiver_draw != "translucent")
      fail(c, n["receiver_draw"], join_key(key, "receiver_draw"),
           "expected mask, wireframe or translucent, " + got(n["receiver_draw"]));
  }
  if (n["look"]) {
    v.look = to_string_value(c, n["look"], join_key(key, "look"), "plain or camera");
    if (v.look != "plain" && v.look != "camera")
      fail(c, n["look"], join_key(key, "look"), "expected plain or camera, " + got(n["look"]));
  }
  if (const YAML::Node e = n["evaluate"]) {
    const std::string ek = join_key(key, "evaluate");
    v.evaluate = true;
    if (e.IsScalar()) {
      v.evaluate = to_bool(c, e, ek);
    } else {
      expect_map(c, e, ek, "true, false or a map of the evaluation's settings");
      check_keys(c, e, ek, {"matcher", "every", "context_px", "full_frame"});
      if (e["matcher"])
        v.matcher =
            path_value(c, e["matcher"], join_key(ek, "matcher"), base, "a matcher file", true).string();
      if (e["every"]) {
        const double k = to_number(c, e["every"], join_key(ek, "every"), "a whole number >= 1");
        if (k < 1 || k > 1e6 || k != std::floor(k))
          fail(c, e["every"], join_key(ek, "every"),
               "expected a whole number in [1, 1000000], " + got(e["every"]));
        v.every = static_cast<int>(k);
      }
      if (e["context_px"]) {
        const double px = to_number(c, e["context_px"], join_key(ek, "context_px"), "pixels >= 0");
        if (px < 0 || px > 1e5 || px != std::floor(px))
          fail(c, e["context_px"], join_key(ek, "context_px"),
               "expected whole pixels in [0, 100000], " + got(e["context_px"]));
        v.context_px = static_cast<int>(px);
      }
      if (e["full_frame"]) v.full_frame = to_bool(c, e["full_frame"], join_key(ek, "full_frame"));
      if (v.full_frame && v.context_px) fail(c, e, ek, "full_frame and context_px exclude each other");
    }
  }
  // The re-augmented frames as files too, per shard, joined per flight by the merge.
  if (const YAML::Node x = n["exports"]) {
    const std::string xk = join_key(key, "exports");
    if (!x.IsSequence())
      fail(c, x, xk, "expected a list of export formats ([mcap, euroc, recording]), " + got(x));
    for (const YAML::Node& f : x) {
      const std::string format = to_string_value(c, f, xk, "an export format");
      if (format == "mcap")
        v.export_mcap = true;
      else if (format == "euroc")
        v.export_euroc = true;
      else if (format == "recording")
        v.export_recording = true;
      else
        fail(c, f, xk,
             "expected mcap, euroc or recording (the formats a shard can write and the merge join), " +
                 got(f));
    }
    if ((v.export_mcap || v.export_euroc || v.export_recording) && v.evaluate)
      fail(c, x, xk,
           "exports are written by replay variants (without evaluate); give them their own variant");
  }
  return v;
}

}  // namespace

Expected<CampaignSpec> parse_campaign(const std::string& text, const fs::path& file) {
  const Context c{kLoad, file.string()};
  return guarded(c, [&]() -> CampaignSpec {
    const YAML::Node root = YAML::Load(text);
    expect_map(c, root, "", "a campaign file (a map)");
    check_keys(c, root, "", {"augrig_campaign", "name", "out", "recordings", "variants", "shards", "slurm"});
    const YAML::Node version = require(c, root, "", "augrig_campaign", "the format version 1");
    if (to_number(c, version, "augrig_campaign", "the format version 1") != 1)
      fail(c, version, "augrig_campaign", "expected the format version 1, " + got(version));
    CampaignSpec s;
    s.file = fs::absolute(file);
    const fs::path base = s.file.parent_path();
    s.name = name_value(c, require(c, root, "", "name", "the campaign's name"), "name");
    s.out = path_value(c, require(c, root, "", "out", "the output folder"), "out", base, "an output folder",
                       false);

    const YAML::Node recs = require(c, root, "", "recordings", "a list of recordings");
    if (!recs.IsSequence() || recs.size() == 0)
      fail(c, recs, "recordings", "expected a list of at least one recording, " + got(recs));
    std::set<std::string> names;
    for (std::size_t i = 0; i < recs.size(); ++i) {
      const std::string key = "recordings[" + std::to_string(i) + "]";
      s.flights.push_back(parse_flight(c, recs[i], key, base));
      if (!names.insert(s.flights.back().name).second)
        fail(c, recs[i], key,
             "two flights are named '" + s.flights.back().name + "': give each a distinct `name:`");
    }

    const YAML::Node vars = root["variants"];
    if (vars) {
      if (!vars.IsSequence() || vars.size() == 0)
        fail(c, vars, "variants", "expected a list of at least one variant, " + got(vars));
      names.clear();
      for (std::size_t i = 0; i < vars.size(); ++i) {
        const std::string key = "variants[" + std::to_string(i) + "]";
        s.variants.push_back(parse_variant(c, vars[i], key, base));
        if (!names.insert(s.variants.back().name).second)
          fail(c, vars[i], key, "two variants are named '" + s.variants.back().name + "'");
      }
    } else {
      VariantSpec recorded;  // as recorded: the statistics only
      recorded.name = "recorded";
      s.variants.push_back(recorded);
    }
    // A EuRoC folder has no receiver poses: a variant must place the receiver for it.
    for (std::size_t i = 0; i < s.flights.size(); ++i)
      if (s.flights[i].kind == FlightKind::kEuroc && s.flights[i].poses.empty())
        for (const VariantSpec& v : s.variants)
          if (v.scene.empty())
            fail(c, recs[i], "recordings[" + std::to_string(i) + "]",
                 "a EuRoC folder holds no receiver poses: give the flight `poses:` (augrig nav's CSV) or "
                 "variant '" +
                     v.name + "' a `scene:`");

    if (const YAML::Node sh = root["shards"]) {
      expect_map(c, sh, "shards", "a map with seconds or task_minutes");
      check_keys(c, sh, "shards", {"seconds", "task_minutes"});
      if (sh["seconds"] && sh["task_minutes"])
        fail(c, sh, "shards", "give seconds or task_minutes, not both");
      if (sh["seconds"]) {
        s.shard_seconds = to_number(c, sh["seconds"], "shards.seconds", "seconds > 0");
        if (!(*s.shard_seconds > 0))
          fail(c, sh["seconds"], "shards.seconds", "expected seconds > 0, " + got(sh["seconds"]));
      }
      if (sh["task_minutes"]) {
        s.task_minutes = to_number(c, sh["task_minutes"], "shards.task_minutes", "minutes > 0");
        if (!(s.task_minutes > 0))
          fail(c, sh["task_minutes"], "shards.task_minutes",
               "expected minutes > 0, " + got(sh["task_minutes"]));
      }
    }
    if (const YAML::Node sl = root["slurm"]) {
      expect_map(c, sl, "slurm", "a map of the Slurm settings");
      check_keys(
          c, sl, "slurm",
          {"partition", "account", "cpus_per_task", "time_safety", "max_array_size", "max_running", "extra"});
      SlurmSpec& q = s.slurm;
      if (sl["partition"]) q.partition = name_value(c, sl["partition"], "slurm.partition");
      if (sl["account"]) q.account = name_value(c, sl["account"], "slurm.account");
      auto whole = [&](const char* k, int lo, int hi) {
        const std::string key = std::string("slurm.") + k;
        const double v = to_number(c, sl[k], key, "a whole number");
        if (v < lo || v > hi || v != std::floor(v))
          fail(c, sl[k], key,
               "expected a whole number in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], " +
                   got(sl[k]));
        return static_cast<int>(v);
      };
      if (sl["cpus_per_task"]) q.cpus_per_task = whole("cpus_per_task", 1, 1024);
      if (sl["max_array_size"]) q.max_array_size = whole("max_array_size", 2, 4000001);
      if (sl["max_running"]) q.max_running = whole("max_running", 0, 1000000);
      if (sl["time_safety"]) {
        q.time_safety = to_number(c, sl["time_safety"], "slurm.time_safety", "a factor >= 1");
        if (!(q.time_safety >= 1 && q.time_safety <= 100))
          fail(c, sl["time_safety"], "slurm.time_safety",
               "expected a factor in [1, 100], " + got(sl["time_safety"]));
      }
      if (const YAML::Node ex = sl["extra"]) {
        if (!ex.IsSequence()) fail(c, ex, "slurm.extra", "expected a list of sbatch options, " + got(ex));
        for (std::size_t i = 0; i < ex.size(); ++i) {
          const std::string key = "slurm.extra[" + std::to_string(i) + "]";
          const std::string o = to_string_value(c, ex[i], key, "an sbatch option such as --qos=long");
          if (o.rfind("--", 0) != 0 || o.find('\n') != std::string::npos)
            fail(c, ex[i], key, "expected an sbatch option starting with --, " + got(ex[i]));
          for (const char* own : {"--array", "--output", "--time", "--mem", "--cpus-per-task", "--job-name"})
            if (o.rfind(own, 0) == 0)
              fail(c, ex[i], key, std::string(own) + " is set by the plan, not by slurm.extra");
          q.extra.push_back(o);
        }
      }
    }
    return s;
  });
}

Expected<CampaignSpec> load_campaign(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) return make_error(kLoad, file.string(), ": cannot read the campaign file");
  std::ostringstream ss;
  ss << in.rdbuf();
  return parse_campaign(ss.str(), file);
}

// ---- Flights and shards ------------------------------------------------------------------------

namespace {

std::string images_of(PixelFormat fl, int wl, int hl, PixelFormat fr, int wr, int hr) {
  if (wl <= 0 || hl <= 0 || wr <= 0 || hr <= 0) return "";
  std::ostringstream o;
  o << to_string(fl) << ' ' << wl << 'x' << hl << " + " << to_string(fr) << ' ' << wr << 'x' << hr;
  return o.str();
}

}  // namespace

Expected<FlightFrames> read_flight_frames(const FlightSpec& flight) {
  FlightFrames f;
  switch (flight.kind) {
    case FlightKind::kMcap: {
      // Read front to back only, so not split. Opened here all the same: a damaged file (cut short,
      // no summary) fails the plan with its reason, not every task that would read it.
      auto src = recorder::McapSource::open(flight.path.string());
      if (!src) return make_error("campaign::read_flight_frames(): ", src.error().message);
      f.splittable = false;
      f.whole_frames = (*src)->frame_count();
      return f;
    }
    case FlightKind::kRecording: {
      auto reader = recorder::RecordingReader::open(flight.path.string());
      if (!reader) return reader.error();
      const std::size_t n = (*reader)->frame_count();
      f.t_ns.reserve(n);
      for (std::size_t i = 0; i < n; ++i) {
        auto info = (*reader)->read_frame_info(i);
        f.t_ns.push_back(info ? std::optional<std::int64_t>(info->raw.t_key_ns) : std::nullopt);
      }
      // The images' sizes and formats: the first frame that decodes, of the first few.
      for (std::size_t i = 0; i < std::min<std::size_t>(n, 16) && f.images.empty(); ++i)
        if (auto fr = (*reader)->read_frame(i, recorder::kPartRaw))
          f.images = images_of(fr->raw.left.image.format(), fr->raw.left.image.width(),
                               fr->raw.left.image.height(), fr->raw.right.image.format(),
                               fr->raw.right.image.width(), fr->raw.right.image.height());
      if (n == 0)
        return make_error("campaign::read_flight_frames(): ", flight.path.string(),
                          ": the recording holds no frames");
      return f;
    }
    case FlightKind::kEuroc: {
      auto src = recorder::EurocSource::open(flight.path.string());
      if (!src) return src.error();
      const fs::path mav0 = (*src)->mav0();
      auto left = recorder::read_euroc_camera_csv((mav0 / "cam0" / "data.csv").string());
      if (!left) return left.error();
      auto right = recorder::read_euroc_camera_csv((mav0 / "cam1" / "data.csv").string());
      if (!right) return right.error();
      // The pairs as EurocSource makes them with the default (exact) pairing: identical stamps.
      std::set<std::int64_t> r;
      for (const auto& row : *right) r.insert(row.t_ns);
      for (const auto& row : *left)
        if (r.count(row.t_ns)) f.t_ns.push_back(row.t_ns);
      std::sort(f.t_ns.begin(), f.t_ns.end());
      // The images' sizes from the first pair, read as a task reads it.
      Frame l, r2;
      if (auto a = (*src)->read(l, std::chrono::seconds(5)); a && *a == ReadStatus::kFrame)
        if (auto b = (*src)->read(r2, std::chrono::seconds(5)); b && *b == ReadStatus::kFrame)
          f.images = images_of(l.image.format(), l.image.width(), l.image.height(), r2.image.format(),
                               r2.image.width(), r2.image.height());
      if (f.t_ns.size() != (*src)->pair_count())
        return make_error("campaign::read_flight_frames(): ", flight.path.string(), ": ", f.t_ns.size(),
                          " pairs by timestamp, but the EuRoC reader makes ", (*src)->pair_count());
      if (f.t_ns.empty())
        return make_error("campaign::read_flight_frames(): ", flight.path.string(), ": no stereo pairs");
      return f;
    }
  }
  return f;
}

FlightClock flight_clock(const FlightFrames& f) {
  FlightClock c;
  const std::size_t n = f.t_ns.size();
  c.elapsed_s.assign(n, 0);
  // The typical frame interval: the median of the steps forward.
  // (A plain flag and value, not an optional: GCC 12 warns of the optional's value as maybe unset.)
  std::vector<std::int64_t> steps;
  bool have_prev = false;
  std::int64_t prev_ns = 0;
  for (const auto& t : f.t_ns) {
    if (!t) continue;
    if (have_prev && *t > prev_ns) steps.push_back(*t - prev_ns);
    have_prev = true, prev_ns = *t;
  }
  std::int64_t typical_ns = 0;
  if (!steps.empty()) {
    std::nth_element(steps.begin(), steps.begin() + static_cast<std::ptrdiff_t>(steps.size() / 2),
                     steps.end());
    typical_ns = steps[steps.size() / 2];
  }
  // Summed in nanoseconds: a clock that never steps back gives exactly (t - t0) / 1e9.
  have_prev = false;
  std::int64_t elapsed_ns = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (const auto& t = f.t_ns[i]) {
      if (have_prev) {
        if (*t > prev_ns) {
          elapsed_ns += *t - prev_ns;
        } else {
          elapsed_ns += typical_ns;
          if (c.steps_back++ == 0) c.first_step_back_frame = i;
          c.largest_step_back_s = std::max(c.largest_step_back_s, static_cast<double>(prev_ns - *t) / 1e9);
        }
      }
      have_prev = true, prev_ns = *t;
    }
    c.elapsed_s[i] = static_cast<double>(elapsed_ns) / 1e9;
  }
  return c;
}

std::vector<Shard> split_flight(const FlightFrames& f, double seconds, std::size_t align) {
  std::vector<Shard> out;
  const std::size_t n = f.t_ns.size();
  align = std::max<std::size_t>(align, 1);
  const std::vector<double> t_s = flight_clock(f).elapsed_s;
  if (!f.splittable || n == 0) {
    out.push_back(Shard{0, 0, f.splittable ? n : f.whole_frames, 0, n ? t_s.back() : 0});
    return out;
  }
  std::size_t from = 0;
  while (from < n) {
    // The first frame at or after the next boundary, moved up to the alignment.
    const double boundary = t_s[from] + seconds;
    std::size_t to = from + 1;
    while (to < n && t_s[to] < boundary) ++to;
    if (to < n) to = std::min(n, (to + align - 1) / align * align);
    if (to <= from) to = std::min(n, from + align);
    out.push_back(Shard{out.size(), from, to - from, t_s[from], t_s[to - 1]});
    from = to;
  }
  return out;
}

std::vector<std::string> task_command(const FlightSpec& flight, const VariantSpec& v, const Shard& shard,
                                      bool whole_flight) {
  std::vector<std::string> a;
  a.push_back(v.evaluate ? "evaluate" : "replay");
  a.push_back(flight.path.string());
  if (!whole_flight) {
    a.insert(a.end(),
             {"--from-frame", std::to_string(shard.from_frame), "--frames", std::to_string(shard.frames)});
  }
  if (!v.rig.empty()) a.insert(a.end(), {"--rig", v.rig});
  if (!v.scene.empty())
    a.insert(a.end(), {"--scene", v.scene});
  else if (!flight.poses.empty())
    a.insert(a.end(), {"--poses", flight.poses.string()});
  if (!v.boom.empty()) a.insert(a.end(), {"--boom", v.boom});
  if (!v.receiver_draw.empty()) a.insert(a.end(), {"--receiver-draw", v.receiver_draw});
  if (v.evaluate) {
    // The plain look: a shard must give the whole run's rows, and the camera look's light and
    // noise estimates build up from a run's first frame (docs/CAMPAIGN.md).
    a.insert(a.end(), {"--look", "plain"});
    if (!v.matcher.empty()) a.insert(a.end(), {"--matcher", v.matcher});
    if (v.every != 1) a.insert(a.end(), {"--every", std::to_string(v.every)});
    if (v.context_px) a.insert(a.end(), {"--context", std::to_string(*v.context_px)});
    if (v.full_frame) a.push_back("--full-frame");
    a.push_back("--no-plot");  // the merge plots the whole flight
  } else {
    a.insert(a.end(), {"--fast", "--headless", "--every", "1000000"});  // the statistics, few images
    if (!v.look.empty()) a.insert(a.end(), {"--look", v.look});
    if (v.export_mcap) a.insert(a.end(), {"--sink", std::string("mcap:") + kTaskOut + "/" + kShardMcap});
    if (v.export_euroc) a.insert(a.end(), {"--sink", kShardEurocSink});
    if (v.export_recording) a.insert(a.end(), {"--record", std::string(kTaskOut) + "/" + kShardRecording});
  }
  // A frame that cannot be read is left out and counted (done.yaml, status, the report): a shard
  // of a damaged recording would otherwise fail on every run.
  a.push_back("--allow-damaged");
  return a;
}

std::vector<Task> plan_tasks(const CampaignSpec& spec, const std::vector<FlightFrames>& frames,
                             const std::vector<std::pair<std::string, TaskCost>>& costs) {
  std::vector<Task> tasks;
  for (const VariantSpec& v : spec.variants) {
    double per_frame_s = 0;
    for (const auto& [name, c] : costs)
      if (name == v.name) per_frame_s = c.per_frame_s;
    for (std::size_t i = 0; i < spec.flights.size(); ++i) {
      const FlightSpec& f = spec.flights[i];
      const FlightFrames& ff = frames[i];
      double seconds = spec.shard_seconds.value_or(0);
      if (!spec.shard_seconds) {
        // A task of task_minutes at the measured cost, in the flight's recorded seconds.
        std::vector<double> dt;
        std::optional<std::int64_t> prev;
        for (const auto& t : ff.t_ns) {
          if (t && prev && *t > *prev) dt.push_back(static_cast<double>(*t - *prev) / 1e9);
          if (t) prev = t;
        }
        std::sort(dt.begin(), dt.end());
        const double frame_s = dt.empty() ? 1.0 / 30 : dt[dt.size() / 2];
        const double frames_per_task = spec.task_minutes * 60 / std::max(per_frame_s, 1e-6);
        seconds = std::max(frame_s, frames_per_task * frame_s);
      }
      const auto shards = split_flight(ff, seconds, static_cast<std::size_t>(v.every));
      for (const Shard& s : shards) {
        Task t;
        t.id = tasks.size();
        t.flight = f.name;
        t.variant = v.name;
        t.shard = s;
        t.out = shard_dir(spec.out, v.name, f.name, s.index);
        t.argv = task_command(f, v, s, !ff.splittable);
        tasks.push_back(std::move(t));
      }
    }
  }
  return tasks;
}

fs::path shard_dir(const fs::path& out, const std::string& variant, const std::string& flight,
                   std::size_t i) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%04zu", i);
  return out / "shards" / variant / flight / buf;
}

const TaskCost* Manifest::cost_of(const std::string& variant) const {
  for (const auto& [v, c] : costs)
    if (v == variant) return &c;
  return nullptr;
}

// ---- The manifest ------------------------------------------------------------------------------

namespace {

std::string full(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

}  // namespace

Status write_manifest(const Manifest& m) {
  YAML::Emitter e;
  e << YAML::BeginMap;
  e << YAML::Key << "augrig_campaign_manifest" << YAML::Value << 1;
  e << YAML::Key << "name" << YAML::Value << m.name;
  e << YAML::Key << "campaign" << YAML::Value << m.campaign_file.string();
  e << YAML::Key << "out" << YAML::Value << m.out.string();
  e << YAML::Key << "augrig" << YAML::Value << m.augrig.string();
  e << YAML::Key << "planned_at" << YAML::Value << m.planned_at;
  e << YAML::Key << "heartbeat_s" << YAML::Value << full(m.heartbeat_s);
  const SlurmSpec& q = m.slurm;
  e << YAML::Key << "slurm" << YAML::Value << YAML::BeginMap << YAML::Key << "partition" << YAML::Value
    << q.partition << YAML::Key << "account" << YAML::Value << q.account << YAML::Key << "cpus_per_task"
    << YAML::Value << q.cpus_per_task << YAML::Key << "time_safety" << YAML::Value << full(q.time_safety)
    << YAML::Key << "max_array_size" << YAML::Value << q.max_array_size << YAML::Key << "max_running"
    << YAML::Value << q.max_running << YAML::Key << "extra" << YAML::Value << YAML::Flow << q.extra
    << YAML::EndMap;
  e << YAML::Key << "costs" << YAML::Value << YAML::BeginSeq;
  for (const auto& [v, c] : m.costs) {
    e << YAML::Flow << YAML::BeginMap << YAML::Key << "variant" << YAML::Value << v << YAML::Key
      << "startup_s" << YAML::Value << full(c.startup_s) << YAML::Key << "per_frame_s" << YAML::Value
      << full(c.per_frame_s) << YAML::Key << "max_rss_bytes" << YAML::Value << c.max_rss_bytes << YAML::Key
      << "measured_on" << YAML::Value << c.measured_on << YAML::EndMap;
  }
  e << YAML::EndSeq;
  e << YAML::Key << "tasks" << YAML::Value << YAML::BeginSeq;
  for (const Task& t : m.tasks) {
    e << YAML::Flow << YAML::BeginMap;
    e << YAML::Key << "id" << YAML::Value << t.id << YAML::Key << "flight" << YAML::Value << t.flight
      << YAML::Key << "variant" << YAML::Value << t.variant << YAML::Key << "shard" << YAML::Value
      << t.shard.index << YAML::Key << "from_frame" << YAML::Value << t.shard.from_frame << YAML::Key
      << "frames" << YAML::Value << t.shard.frames << YAML::Key << "t_from_s" << YAML::Value
      << full(t.shard.t_from_s) << YAML::Key << "t_to_s" << YAML::Value << full(t.shard.t_to_s) << YAML::Key
      << "out" << YAML::Value << t.out.string();
    e << YAML::Key << "argv" << YAML::Value << YAML::Flow << t.argv;
    e << YAML::EndMap;
  }
  e << YAML::EndSeq << YAML::EndMap;
  if (!e.good()) return make_error("campaign::write_manifest(): ", m.file.string(), ": ", e.GetLastError());
  // Written beside and renamed: a task never reads half a manifest.
  const fs::path tmp = m.file.string() + ".tmp";
  {
    std::ofstream o(tmp, std::ios::binary);
    o << "# augrig campaign manifest: one task per shard and variant (docs/CAMPAIGN.md). Written by\n"
         "# `augrig campaign plan`; tasks read it. Edit the campaign file and plan again instead.\n"
      << e.c_str() << "\n";
    if (!o.flush()) return make_error("campaign::write_manifest(): ", tmp.string(), ": cannot write");
  }
  std::error_code ec;
  fs::rename(tmp, m.file, ec);
  if (ec) return make_error("campaign::write_manifest(): ", m.file.string(), ": ", ec.message());
  return {};
}

Expected<Manifest> load_manifest(const fs::path& file) {
  const Context c{"campaign::load_manifest(): ", file.string()};
  std::ifstream in(file, std::ios::binary);
  if (!in)
    return make_error(
        c.prefix, file.string(),
        ": cannot read the manifest (plan the campaign first: augrig campaign plan CAMPAIGN.yaml)");
  std::ostringstream ss;
  ss << in.rdbuf();
  return guarded(c, [&]() -> Manifest {
    const YAML::Node root = YAML::Load(ss.str());
    expect_map(c, root, "", "a campaign manifest");
    const YAML::Node version = require(c, root, "", "augrig_campaign_manifest", "the manifest version 1");
    if (to_number(c, version, "augrig_campaign_manifest", "1") != 1)
      fail(c, version, "augrig_campaign_manifest", "expected version 1, " + got(version));
    Manifest m;
    m.file = fs::absolute(file);
    m.name = to_string_value(c, require(c, root, "", "name", "a name"), "name", "a name");
    m.campaign_file = to_string_value(c, require(c, root, "", "campaign", "a path"), "campaign", "a path");
    m.out = to_string_value(c, require(c, root, "", "out", "a path"), "out", "a path");
    m.augrig = to_string_value(c, require(c, root, "", "augrig", "a path"), "augrig", "a path");
    if (root["planned_at"]) m.planned_at = root["planned_at"].Scalar();
    if (root["heartbeat_s"]) m.heartbeat_s = to_number(c, root["heartbeat_s"], "heartbeat_s", "seconds");
    if (const YAML::Node q = root["slurm"]) {
      expect_map(c, q, "slurm", "the Slurm settings");
      auto num = [&](const char* k, double fallback) {
        return q[k] ? to_number(c, q[k], std::string("slurm.") + k, "a number") : fallback;
      };
      if (q["partition"]) m.slurm.partition = q["partition"].Scalar();
      if (q["account"]) m.slurm.account = q["account"].Scalar();
      m.slurm.cpus_per_task = static_cast<int>(num("cpus_per_task", m.slurm.cpus_per_task));
      m.slurm.time_safety = num("time_safety", m.slurm.time_safety);
      m.slurm.max_array_size = static_cast<int>(num("max_array_size", m.slurm.max_array_size));
      m.slurm.max_running = static_cast<int>(num("max_running", m.slurm.max_running));
      if (q["extra"])
        for (const auto& x : q["extra"]) m.slurm.extra.push_back(x.Scalar());
    }
    if (const YAML::Node costs = root["costs"])
      for (std::size_t i = 0; i < costs.size(); ++i) {
        const YAML::Node n = costs[i];
        const std::string key = "costs[" + std::to_string(i) + "]";
        TaskCost tc;
        tc.startup_s =
            to_number(c, require(c, n, key, "startup_s", "seconds"), key + ".startup_s", "seconds");
        tc.per_frame_s =
            to_number(c, require(c, n, key, "per_frame_s", "seconds"), key + ".per_frame_s", "seconds");
        tc.max_rss_bytes = static_cast<std::int64_t>(
            to_number(c, require(c, n, key, "max_rss_bytes", "bytes"), key + ".max_rss_bytes", "bytes"));
        if (n["measured_on"]) tc.measured_on = n["measured_on"].Scalar();
        m.costs.emplace_back(
            to_string_value(c, require(c, n, key, "variant", "a name"), key + ".variant", "a name"), tc);
      }
    const YAML::Node tasks = require(c, root, "", "tasks", "the list of tasks");
    if (!tasks.IsSequence()) fail(c, tasks, "tasks", "expected a list, " + got(tasks));
    for (std::size_t i = 0; i < tasks.size(); ++i) {
      const YAML::Node n = tasks[i];
      const std::string key = "tasks[" + std::to_string(i) + "]";
      expect_map(c, n, key, "a task");
      auto num = [&](const char* k) {
        return to_number(c, require(c, n, key, k, "a number"), key + "." + k, "a number");
      };
      Task t;
      t.id = static_cast<std::size_t>(num("id"));
      if (t.id != i)
        fail(c, n, key + ".id", "expected " + std::to_string(i) + " (tasks in order), " + got(n["id"]));
      t.flight = to_string_value(c, require(c, n, key, "flight", "a name"), key + ".flight", "a name");
      t.variant = to_string_value(c, require(c, n, key, "variant", "a name"), key + ".variant", "a name");
      t.shard.index = static_cast<std::size_t>(num("shard"));
      t.shard.from_frame = static_cast<std::size_t>(num("from_frame"));
      t.shard.frames = static_cast<std::size_t>(num("frames"));
      t.shard.t_from_s = num("t_from_s");
      t.shard.t_to_s = num("t_to_s");
      t.out = to_string_value(c, require(c, n, key, "out", "a folder"), key + ".out", "a folder");
      const YAML::Node argv = require(c, n, key, "argv", "the command's arguments");
      if (!argv.IsSequence() || argv.size() < 2)
        fail(c, argv, key + ".argv", "expected the command's arguments, " + got(argv));
      for (const auto& x : argv) t.argv.push_back(x.Scalar());
      m.tasks.push_back(std::move(t));
    }
    return m;
  });
}

double wall_clock_s() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

std::string utc_now_iso() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char b[32];
  std::strftime(b, sizeof b, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return b;
}

std::string slurm_time(double seconds) {
  const long long minutes = std::max(1LL, static_cast<long long>(std::ceil(seconds / 60.0)));
  char b[32];
  std::snprintf(b, sizeof b, "%lld-%02lld:%02lld:00", minutes / 1440, minutes / 60 % 24, minutes % 60);
  return b;
}

}  // namespace augrig::campaign
