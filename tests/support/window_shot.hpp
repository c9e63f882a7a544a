// Screenshots of augrig's live window taken by a command's --screenshot-at N, checked against the
// frame the window showed (from a recording the same command made): both views show an image,
// the boom is drawn where the masks say and the raw image elsewhere, and the HUD's occlusion
// panel is filled (its plots drawn, not "no frame yet").
#pragma once

#include <optional>
#include <string>

#include "recorder/record.hpp"

namespace augrig::test {

struct Rect {
  int x = 0, y = 0, w = 0, h = 0;
};
// "screenshot PATH (framebuffer WxH; left view x,y,w,h; right view ...; hud ...; pair N)".
struct WindowShot {
  std::string path;
  int width = 0, height = 0;
  Rect views[2], hud;
  std::uint64_t pair = 0;
};
std::optional<WindowShot> parse_window_shot(const std::string& log);

// Checks the screenshot with GoogleTest assertions; `frame` is the recorded pair shown (its raw
// images and masks).
void check_window_shot(const WindowShot& shot, const recorder::FrameRecord& frame);

}  // namespace augrig::test
