// replay://DIR[?rate=R|fast&late=drop|keep&loop=1&passes=N&from_frame=N&seek_s=S]: a recording
// (recorder/replay_source.hpp), paced at R times its real rate (1) or as fast as read (fast,
// lockstep), looped, from a frame or a time. Paced, a frame that comes too late is lost, live-like
// (late=keep: every frame). loop=1 plays it forever, passes=N the range N times. Its player is
// OpenedSourceInfo::replay, for pause, step and seek.
// replay://FILE.mcap[?rate=fast]: an MCAP file from augrig export --format mcap, as fast as read,
// once (lockstep).
// Both hold pairs already: each stereo frame comes as its left Frame, then its right one.
#include "pipeline/sources/schemes.hpp"
#include "recorder/mcap_export.hpp"
#include "recorder/replay_source.hpp"

namespace augrig::pipeline {
namespace {

// replay://FILE.mcap
Expected<OpenedSource> open_mcap(const SourceUri& u) {
  OpenedSource out;
  // An MCAP file from augrig export --format mcap: its frames as fast as read, once (lockstep).
  if (Status s = u.check_known({"rate"}); !s) return s.error();
  if (u.get("rate", "fast") != "fast")
    return uri_error(u,
                     "rate: an MCAP file plays as fast as it is read (rate=fast); pacing needs a recording");
  auto src = recorder::McapSource::open(u.target);
  if (!src) return src.error();
  out.options.lossless = true;
  out.options.skip_read_errors = true;  // a frame that cannot be decoded is skipped (the error says which)
  out.options.pairing.mode = PairingMode::kAdjacent;
  out.sources.push_back(std::move(*src));
  return out;
}

}  // namespace

// replay://DIR: a recording, paced or fast, looped, from a frame or a time.
Expected<OpenedSource> open_replay(const SourceUri& u) {
  if (recorder::is_mcap_path(u.target)) return open_mcap(u);
  OpenedSource out;
  if (Status s = u.check_known({"rate", "loop", "passes", "from_frame", "seek_s", "late"}); !s)
    return s.error();
  recorder::ReplayOptions o;
  // The StereoSource's capture thread already reads the recording ahead of the pipeline (its
  // queue): a decode thread of the ReplaySource's own would only add a hand-off.
  o.read_ahead = 0;
  const std::string rate = u.get("rate", "1");
  if (rate == "fast") {
    o.mode = recorder::ReplayMode::kFast;
  } else {
    auto r = u.get_number("rate", 1.0, 0, 1e6);
    if (!r) return r.error();
    if (*r <= 0) return uri_error(u, "rate: expected a number > 0 or 'fast'");
    o.mode = recorder::ReplayMode::kRealRate;
    o.rate = *r;
    o.drop_late = true;  // live-like: late frames are lost, as a camera's would be
  }
  const std::string late = u.get("late", "drop");
  if (late != "drop" && late != "keep")
    return uri_error(u, "late: expected drop or keep, got '" + late + "'");
  if (late == "keep") o.drop_late = false;  // every frame, late or not
  // loop=1: forever; passes=N: the range N times.
  o.passes = u.get("loop", "0") == "1" ? 0 : 1;
  if (u.has("passes")) {
    auto n = u.get_integer("passes", 1, 1, 1'000'000);
    if (!n) return n.error();
    o.passes = static_cast<int>(*n);
  }
  auto start = playback_start(u);
  if (!start) return start.error();
  o.start_frame = start->frame;
  o.start_offset_ns = start->offset_ns;
  auto src = recorder::ReplaySource::open(u.target, o);
  if (!src) return src.error();
  out.options.lossless = o.mode == recorder::ReplayMode::kFast || !o.drop_late;
  // A damaged frame is skipped (the recording says which), the others play on.
  out.options.skip_read_errors = true;
  // A recording holds pairs already: each recorded stereo frame comes as its left Frame, then its
  // right one, and they pair as delivered (a loop or a seek goes back in time).
  out.options.pairing.mode = PairingMode::kAdjacent;
  out.replay = src->get();
  out.sources.push_back(std::move(*src));
  return out;
}

}  // namespace augrig::pipeline
