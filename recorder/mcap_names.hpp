// The names an augrig MCAP file is written and read by (docs/MCAP.md; the topics are listed in
// mcap_export.hpp): the Metadata record of the recording's meta table, the tf frames and the
// cameras' topic prefixes. Shared by the format's writer (mcap_export.hpp) and its reader
// (mcap_source.hpp), so that the two cannot drift apart.
#pragma once

namespace augrig::recorder {

// The Metadata record holding the recording's meta table (rig_yaml, scene, clock_domains, ...).
inline constexpr const char* kMcapRecordingMetadata = "augrig_recording";

namespace mcap_names {

inline constexpr const char* kBodyFrame = "tanker_body";        // /tf_static's and /tf's parent
inline constexpr const char* kReceiverFrame = "receiver_body";  // /tf's child
// The cameras' frame_id, and their topics' prefixes (/left/..., /right/...).
inline constexpr const char* kCameraFrames[2] = {"left_camera", "right_camera"};
inline constexpr const char* kCameraNames[2] = {"left", "right"};

}  // namespace mcap_names
}  // namespace augrig::recorder
