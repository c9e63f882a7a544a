#include "app/display_hud.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include <imgui.h>

#include "recorder/record.hpp"

namespace augrig::app::hud {

namespace {

const ImVec4 kRed(1.0f, 0.3f, 0.25f, 1.0f);
const ImVec4 kOrange(1.0f, 0.7f, 0.2f, 1.0f);
const ImVec4 kGreen(0.4f, 0.9f, 0.4f, 1.0f);
const ImVec4 kGrey(0.65f, 0.65f, 0.65f, 1.0f);

// "12.3" or "-" for unknown (NaN).
std::string num(double v, const char* fmt = "%.1f") {
  if (!std::isfinite(v)) return "-";
  char b[48];
  std::snprintf(b, sizeof b, fmt, v);
  return b;
}

const char* fix_name(nav::FixQuality f) {
  switch (f) {
    case nav::FixQuality::kInvalid:
      return "no fix";
    case nav::FixQuality::kSingle:
      return "single";
    case nav::FixQuality::kDgps:
      return "DGPS";
    case nav::FixQuality::kPps:
      return "PPS";
    case nav::FixQuality::kRtkFixed:
      return "RTK fixed";
    case nav::FixQuality::kRtkFloat:
      return "RTK float";
    case nav::FixQuality::kDeadReckoning:
      return "dead reckoning";
  }
  return "?";
}

void plot(const char* label, const std::deque<OcclusionHistory::Sample>& s,
          float OcclusionHistory::Sample::*field, float width) {
  std::vector<float> v;
  v.reserve(s.size());
  for (const auto& x : s) v.push_back(x.*field);
  float hi = 1.0f;
  for (float x : v) hi = std::max(hi, x);
  char overlay[64];
  std::snprintf(overlay, sizeof overlay, "%s %s%%", label, v.empty() ? "-" : num(v.back(), "%.2f").c_str());
  ImGui::PlotLines("##plot", v.data(), static_cast<int>(v.size()), 0, overlay, 0.0f, hi * 1.1f,
                   ImVec2(width, ImGui::GetTextLineHeight() * 3));
}

}  // namespace

void OcclusionHistory::add(double t_s, const OcclusionStats& s) {
  samples_.push_back({t_s, static_cast<float>(s.occluded_pct_left), static_cast<float>(s.occluded_pct_right),
                      static_cast<float>(s.boom_pct_left), static_cast<float>(s.boom_pct_right)});
}

void OcclusionHistory::trim(double now_s, double window_s) {
  while (!samples_.empty() && samples_.front().t_s < now_s - window_s) samples_.pop_front();
}

std::array<float, 3> panel_background(const std::array<float, 3>& under) {
  const ImVec4 bg = ImGui::GetStyle().Colors[ImGuiCol_WindowBg];
  return {bg.x * bg.w + under[0] * (1.0f - bg.w), bg.y * bg.w + under[1] * (1.0f - bg.w),
          bg.z * bg.w + under[2] * (1.0f - bg.w)};
}

PanelActions draw_status_panel(const HudState& hud, const PanelState& panel, const OcclusionHistory& history,
                               const ImVec2& pos, const ImVec2& size) {
  PanelActions act;
  ImGui::SetNextWindowPos(pos);
  ImGui::SetNextWindowSize(size);
  // No background of ImGui's own: the display clears the panel's rectangle to the same colour
  // (panel_background()), which llvmpipe does for about a tenth of blending a quad over it.
  ImGui::Begin("Status", nullptr,
               ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoCollapse |
                   ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoFocusOnAppearing |
                   ImGuiWindowFlags_NoBackground);
  const float col = ImGui::GetContentRegionAvail().x * 0.5f;  // the left child takes 60 %

  // Left column: the pipeline; right column: occlusion and its history.
  ImGui::BeginChild("left", ImVec2(col * 1.2f, 0), false);
  if (hud.stale_pose) ImGui::TextColored(kRed, "STALE POSE: boom and masks use an old receiver pose");
  ImGui::Text("Cameras  L %s  R %s fps   display %s fps", num(hud.fps[0]).c_str(), num(hud.fps[1]).c_str(),
              num(panel.display_fps).c_str());
  ImGui::Text("Skew     p50 %s  p99 %s ms", num(hud.skew_p50_ms, "%.2f").c_str(),
              num(hud.skew_p99_ms, "%.2f").c_str());
  std::uint64_t total = 0;
  for (auto d : hud.drops) total += d;
  const ImVec4 drop_colour = total ? kOrange : ImGui::GetStyleColorVec4(ImGuiCol_Text);
  std::string drops[2] = {"Drops   ", "        "};
  for (std::size_t i = 0; i < recorder::kAllDropStages.size(); ++i)
    drops[i < 3 ? 0 : 1] +=
        " " + std::string(to_string(recorder::kAllDropStages[i])) + " " + std::to_string(hud.drops[i]);
  ImGui::TextColored(drop_colour, "%s", drops[0].c_str());
  ImGui::TextColored(drop_colour, "%s", drops[1].c_str());
  ImGui::Text("Nav      %s", hud.nav.status.empty() ? "-" : hud.nav.status.c_str());
  ImGui::Text("         %s, age %s s, sigma %s m %s deg", fix_name(hud.nav.fix),
              num(hud.nav.age_s, "%.2f").c_str(), num(hud.nav.sigma_pos_m, "%.3f").c_str(),
              num(hud.nav.sigma_att_deg, "%.2f").c_str());
  // The online camera clocks (run --camera-clock online): grey until an estimate is applied.
  for (const std::string& c : hud.camera_clocks)
    ImGui::TextColored(
        c.find("  applied") != std::string::npos ? ImGui::GetStyleColorVec4(ImGuiCol_Text) : kGrey,
        "Clock    %s", c.c_str());
  ImGui::Text("Latency  display %s / %s ms (p50 / p99)", num(hud.latency_display.p50_ms).c_str(),
              num(hud.latency_display.p99_ms).c_str());
  ImGui::Text("         recorder %s / %s ms", num(hud.latency_recorder.p50_ms).c_str(),
              num(hud.latency_recorder.p99_ms).c_str());
  if (hud.recording)
    ImGui::TextColored(kRed, "REC      %s",
                       hud.recording_path.empty() ? "(recording)" : hud.recording_path.c_str());
  else
    ImGui::TextColored(kGrey, "Not recording");
  ImGui::Text("Boom     %s, el %.1f az %.1f deg, ext %.2f m", std::string(to_string(hud.boom_mode)).c_str(),
              rad_to_deg(panel.boom.elevation_rad), rad_to_deg(panel.boom.azimuth_rad),
              panel.boom.extension_m);
  ImGui::Separator();
  // Controls: the same actions as the shortcuts (F1 lists them).
  static const DisplayBoomMode kModes[] = {DisplayBoomMode::kFixed, DisplayBoomMode::kScripted,
                                           DisplayBoomMode::kTrackReceptacle, DisplayBoomMode::kInteractive};
  for (DisplayBoomMode m : kModes) {
    if (m != kModes[0]) ImGui::SameLine();
    if (ImGui::RadioButton(std::string(to_string(m)).c_str(), hud.boom_mode == m)) act.boom_mode = m;
  }
  act.toggle_recording = ImGui::Button(hud.recording ? "Stop rec" : "Record");
  ImGui::SameLine();
  act.toggle_pause = ImGui::Button(hud.paused ? "Resume" : "Pause");
  ImGui::SameLine();
  act.screenshot = ImGui::Button("Screenshot");
  ImGui::SameLine();
  act.clip = ImGui::Button(panel.clip ? "Stop clip" : "Clip");
  ImGui::SameLine();
  act.help = ImGui::Button("Help");
  int overlay = static_cast<int>(panel.overlay);
  ImGui::SetNextItemWidth(col * 0.55f);
  if (ImGui::Combo("Masks", &overlay, "off\0Fig. 8 occlusion\0Fig. 7b boom overlap\0"))
    act.overlay = static_cast<MaskOverlay>(overlay);
  ImGui::SameLine();
  bool validation = panel.validation;
  if (ImGui::Checkbox("Validation", &validation)) act.validation = validation;
  float depth = static_cast<float>(panel.frustum_depth_m);
  ImGui::SetNextItemWidth(col * 0.55f);
  if (ImGui::SliderFloat("Frusta", &depth, 5.0f, 100.0f, "%.0f m")) act.frustum_depth_m = depth;
  ImGui::SameLine();
  act.reset_view = ImGui::Button("Reset view");
  if (panel.playback && panel.playback->frame_count > 0) {
    // The recording's timeline: drag to scrub (each position a seek), step one frame.
    const pipeline::Playback& pb = *panel.playback;
    ImGui::Text("Replay   frame %zu of %zu, t %.2f of %.2f s%s", pb.frame, pb.frame_count, pb.t_s, pb.duration_s,
                pb.pass ? (" (pass " + std::to_string(pb.pass + 1) + ")").c_str() : "");
    int frame = static_cast<int>(pb.frame);
    ImGui::SetNextItemWidth(col * 0.9f);
    if (ImGui::SliderInt("##timeline", &frame, 0, static_cast<int>(pb.frame_count) - 1, "frame %d") &&
        frame != static_cast<int>(pb.frame))
      act.seek_frame = static_cast<std::size_t>(frame);
    ImGui::SameLine();
    if (ImGui::Button("Step")) act.steps = 1;
    // The playback rate: as fast as the pipeline goes, or real rate times a factor.
    static const double kRates[] = {0.0, 0.25, 0.5, 1.0, 2.0, 4.0};
    static const char* kRateNames = "fast\0x0.25\0x0.5\0x1\0x2\0x4\0";
    int current = 0;
    for (int i = 0; i < 6; ++i)
      if (kRates[i] == pb.rate) current = i;
    int chosen = current;
    ImGui::SameLine();
    ImGui::SetNextItemWidth(col * 0.25f);
    if (ImGui::Combo("Rate", &chosen, kRateNames) && chosen != current) act.rate = kRates[chosen];
  }
  if (panel.clip) ImGui::TextColored(kRed, "CLIP     %d frames", panel.clip_frames);
  if (!panel.last_screenshot.empty()) ImGui::TextColored(kGrey, "Saved    %s", panel.last_screenshot.c_str());
  if (hud.paused) ImGui::TextColored(kOrange, "PAUSED");
  for (const std::string& m : hud.messages) ImGui::TextColored(kOrange, "%s", m.c_str());
  for (const std::string& m : panel.own_messages) ImGui::TextColored(kOrange, "%s", m.c_str());
  ImGui::EndChild();

  ImGui::SameLine();
  ImGui::BeginChild("right", ImVec2(0, 0), false);
  if (hud.occlusion) {
    const OcclusionStats& s = *hud.occlusion;
    ImGui::Text("Receiver %.2f%% L %.2f%% R of image", s.receiver_pct_left, s.receiver_pct_right);
    ImGui::Text("Boom     %.2f%% L %.2f%% R of image", s.boom_pct_left, s.boom_pct_right);
    ImGui::Text("Overlap  %.2f%% of the boom's pixels", s.boom_overlap_pct_union);
    ImGui::Text("Occluded %.2f%% L %.2f%% R of receiver", s.occluded_pct_left, s.occluded_pct_right);
  } else {
    ImGui::TextColored(kGrey, "Occlusion: no frame yet");
  }
  ImGui::Text("Last %.0f s:", panel.plot_seconds);
  const float w = ImGui::GetContentRegionAvail().x;
  ImGui::PushID("occl_l");
  plot("receiver occluded L", history.samples(), &OcclusionHistory::Sample::occluded_left, w);
  ImGui::PopID();
  ImGui::PushID("occl_r");
  plot("receiver occluded R", history.samples(), &OcclusionHistory::Sample::occluded_right, w);
  ImGui::PopID();
  ImGui::PushID("boom_l");
  plot("boom L of image", history.samples(), &OcclusionHistory::Sample::boom_left, w);
  ImGui::PopID();
  ImGui::EndChild();
  ImGui::End();
  return act;
}

void draw_view_label(const char* name, const HudState& hud, const ImVec2& pos) {
  ImDrawList* dl = ImGui::GetBackgroundDrawList();
  std::string text = name;
  dl->AddText(pos, IM_COL32(230, 230, 230, 255), text.c_str());
  float x = pos.x + ImGui::CalcTextSize(text.c_str()).x + ImGui::GetFontSize();
  auto tag = [&](const char* t, ImU32 colour) {
    dl->AddText(ImVec2(x, pos.y), colour, t);
    x += ImGui::CalcTextSize(t).x + ImGui::GetFontSize();
  };
  if (hud.paused) tag("PAUSED", IM_COL32(255, 180, 50, 255));
  if (hud.recording) tag("REC", IM_COL32(255, 70, 60, 255));
  if (hud.stale_pose) tag("STALE POSE", IM_COL32(255, 70, 60, 255));
}

std::array<float, 4> draw_help_overlay(const ImVec2& display_size, bool* open) {
  ImGui::SetNextWindowPos(ImVec2(display_size.x * 0.5f, display_size.y * 0.5f), ImGuiCond_Always,
                          ImVec2(0.5f, 0.5f));
  // Sized from the text up front: an auto-sized window would spend its first frame measuring,
  // invisible, and a screenshot right after F1 would miss it.
  const ImGuiStyle& st = ImGui::GetStyle();
  float keys_w = 0, actions_w = 0;
  for (const Shortcut& s : display_shortcuts()) {
    keys_w = std::max(keys_w, ImGui::CalcTextSize(s.keys).x);
    actions_w = std::max(actions_w, ImGui::CalcTextSize(s.action).x);
  }
  const float rows = static_cast<float>(display_shortcuts().size());
  const ImVec2 size(keys_w + actions_w + 4 * st.CellPadding.x + 2 * st.WindowPadding.x + st.ItemSpacing.x,
                    rows * (ImGui::GetTextLineHeight() + 2 * st.CellPadding.y) + ImGui::GetFrameHeight() +
                        2 * st.WindowPadding.y + st.ItemSpacing.y);
  ImGui::SetNextWindowSize(size, ImGuiCond_Always);
  ImGui::SetNextWindowBgAlpha(0.92f);
  ImGui::Begin("Shortcuts (F1, H or ? to close)", open,
               ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoCollapse |
                   ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoScrollbar);
  if (ImGui::BeginTable("keys", 2, ImGuiTableFlags_RowBg | ImGuiTableFlags_BordersInnerV)) {
    ImGui::TableSetupColumn("keys", ImGuiTableColumnFlags_WidthFixed, keys_w);
    ImGui::TableSetupColumn("action", ImGuiTableColumnFlags_WidthFixed, actions_w);
    for (const Shortcut& s : display_shortcuts()) {
      ImGui::TableNextRow();
      ImGui::TableSetColumnIndex(0);
      ImGui::TextUnformatted(s.keys);
      ImGui::TableSetColumnIndex(1);
      ImGui::TextUnformatted(s.action);
    }
    ImGui::EndTable();
  }
  const ImVec2 p = ImGui::GetWindowPos(), sz = ImGui::GetWindowSize();
  ImGui::End();
  return {p.x, p.y, sz.x, sz.y};
}

}  // namespace augrig::app::hud
