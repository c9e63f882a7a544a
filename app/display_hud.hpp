// The display's HUD, drawn with Dear ImGui (internal to app/display.cpp): the status panel (rates,
// skew, drops by stage, nav, the camera clocks, occlusion, latency, recording, boom, messages and
// the occlusion plot over the last seconds, with buttons for the same actions as the shortcuts), the
// view labels and the help overlay listing every shortcut. Needs a current ImGui frame.
#pragma once

#include <array>
#include <deque>
#include <optional>
#include <string>
#include <vector>

#include "app/display.hpp"

struct ImVec2;

namespace augrig::app::hud {

// Occlusion percentages of the recent frames, for the plot.
class OcclusionHistory {
 public:
  struct Sample {
    double t_s = 0;  // display clock when the frame arrived
    float occluded_left = 0, occluded_right = 0, boom_left = 0, boom_right = 0;
  };
  void add(double t_s, const OcclusionStats& s);
  void trim(double now_s, double window_s);  // drops samples older than the window
  const std::deque<Sample>& samples() const { return samples_; }

 private:
  std::deque<Sample> samples_;
};

// What the display itself knows, shown beside the pipeline's HudState.
struct PanelState {
  double display_fps = 0;
  MaskOverlay overlay = MaskOverlay::kOff;
  bool validation = false;
  bool help = false;
  bool clip = false;
  int clip_frames = 0;
  std::string last_screenshot;
  std::vector<std::string> own_messages;  // the display's recent errors and notes
  BoomArticulation boom;
  double plot_seconds = 10;
  double frustum_depth_m = 25;  // the world view's slider edits this
  std::optional<pipeline::Playback> playback;  // a recording's position: the timeline is shown
};

// Buttons pressed this frame; the display applies them like the matching shortcut.
struct PanelActions {
  std::optional<DisplayBoomMode> boom_mode;
  bool toggle_recording = false, toggle_pause = false, screenshot = false, clip = false, help = false,
       reset_view = false;
  std::optional<MaskOverlay> overlay;
  std::optional<bool> validation;
  std::optional<double> frustum_depth_m;
  int steps = 0;                          // playback: frames to step
  std::optional<std::size_t> seek_frame;  // playback: the timeline was dragged here
  std::optional<double> rate;             // playback: a rate was chosen (0: as fast as possible)
};

// The status panel's background over `under` (RGB 0..1): the panel draws none itself, its owner
// clears the panel's rectangle to this before drawing it.
std::array<float, 3> panel_background(const std::array<float, 3>& under);

// The status panel, placed at `pos` with `size` (ImGui coordinates).
PanelActions draw_status_panel(const HudState& hud, const PanelState& panel, const OcclusionHistory& history,
                               const ImVec2& pos, const ImVec2& size);

// A one-line label above a view (view name, pause, recording, stale pose), in the strip at `pos`.
void draw_view_label(const char* name, const HudState& hud, const ImVec2& pos);

// The help overlay, centred in `display_size`; returns its rectangle (ImGui coordinates) as
// {x, y, w, h}. `open` is cleared when the user closes it.
std::array<float, 4> draw_help_overlay(const ImVec2& display_size, bool* open);

}  // namespace augrig::app::hud
