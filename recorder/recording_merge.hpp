// merge_recordings(): the recordings of one flight's shards joined in order into one recording, as
// one unsharded run would have written it (a campaign's `exports: [recording]`: each shard is
// `augrig replay FLIGHT --from-frame A --frames N --record DIR`; docs/CAMPAIGN.md).
//
//   recorder::RecordingMergeReport report;
//   Status s = recorder::merge_recordings({"t0/recording", "t1/recording"}, "out/recording",
//                                         flight_reader.get(), report);
//
// What goes in, part by part in the order given: the frames, renumbered to follow on, with their
// blobs copied as stored (nothing decoded or recompressed) and their depth rows; each part's events,
// drops and look updates; the nav inputs of `nav_from` (the flight's own recording: a replay does
// not record them) when given, else the parts' own. `meta`: the first part's (rig, scene, codecs,
// source), `merged_from` naming the parts, and the summary re-added from the parts (frames, nav
// inputs, events, look updates from the merged tables; drops by stage and bytes summed; status
// "ok" only when every part's is, else the first other status with its part).
//
// Errors ("recorder::merge_recordings(): PART: what"): no parts, a part that is not a recording or
// was not closed (no summary: a shard still running, or killed), a part of another schema version
// or another rig, parts whose frames overlap in time (each part's first t_ns must follow the
// previous part's last). OUT/recording.sqlite is written under a temporary name and renamed when
// complete (an earlier merge there is replaced), so a failed merge leaves nothing half-written.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "core/expected.hpp"

namespace augrig::recorder {

class RecordingReader;

struct RecordingMergeReport {
  std::size_t parts = 0;
  std::size_t frames = 0;
  std::size_t nav_inputs = 0;
  std::size_t events = 0;
  std::size_t look_updates = 0;
};

Status merge_recordings(const std::vector<std::string>& parts, const std::string& out_dir,
                        const RecordingReader* nav_from, RecordingMergeReport& report);

}  // namespace augrig::recorder
