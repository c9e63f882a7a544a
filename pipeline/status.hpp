// What the pipeline says about itself while it runs, in the words and units an operator reads: the
// nav verdict of the current frame and latencies from mid-exposure. The live window's HUD shows
// these (app/display.hpp); NaN means "not known" (shown as "-").
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "nav/types.hpp"
#include "render/stats.hpp"

namespace augrig::pipeline {

inline constexpr double kHudUnknown = std::numeric_limits<double>::quiet_NaN();

struct NavHud {
  std::string status;  // plain words, e.g. "fused (GPS+IMU)", "dead reckoning", "no nav"
  nav::FixQuality fix = nav::FixQuality::kInvalid;
  double age_s = kHudUnknown;          // since the last nav update used
  double sigma_pos_m = kHudUnknown;    // 1-sigma of the relative position
  double sigma_att_deg = kHudUnknown;  // 1-sigma of the relative attitude
};

struct LatencyHud {
  double p50_ms = kHudUnknown, p99_ms = kHudUnknown;  // mid-exposure to the stage
};

// How the boom is flown (render/boom_control.hpp's three modes, plus the operator's hands).
enum class DisplayBoomMode { kFixed, kScripted, kTrackReceptacle, kInteractive };
std::string_view to_string(DisplayBoomMode m);

// Boom nudges from the arrow keys or a joystick (summed since the last poll), in the boom's
// articulation units. The owner adds them to the interactive boom and clamps to the rig's limits.
struct BoomNudge {
  double elevation_rad = 0, azimuth_rad = 0, extension_m = 0;
  bool any() const { return elevation_rad != 0 || azimuth_rad != 0 || extension_m != 0; }
};

// Everything the HUD shows, filled by the pipeline's owner. NaN: not known (shown as "-").
struct HudState {
  std::array<double, 2> fps = {kHudUnknown, kHudUnknown};       // frames per second delivered, per camera
  double skew_p50_ms = kHudUnknown, skew_p99_ms = kHudUnknown;  // |left - right| mid-exposure of the pairs
  std::array<std::uint64_t, 5> drops{};  // by recorder::DropStage, in kAllDropStages order
  NavHud nav;
  std::optional<OcclusionStats> occlusion;  // the current frame's (also plotted over time)
  LatencyHud latency_display, latency_recorder;
  bool recording = false;
  std::string recording_path;
  bool paused = false;
  DisplayBoomMode boom_mode = DisplayBoomMode::kFixed;
  std::vector<std::string> messages;  // faults in plain words: "left camera lost 0.6 s ago"
  bool stale_pose = false;            // the receiver pose is older than the pipeline allows
  // Each camera's online clock estimate, a line each (CameraClockOnlineStatus::hud_text()); empty: off.
  std::vector<std::string> camera_clocks;
};

}  // namespace augrig::pipeline
