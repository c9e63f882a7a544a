// window_runner (window_runner.hpp): the pipeline on a worker thread, the window's loop here.
#include "app/window_runner.hpp"

#include <chrono>
#include <exception>
#include <memory>
#include <optional>
#include <sstream>
#include <thread>
#include <vector>

#include "app/cli.hpp"
#include "app/display.hpp"
#include "core/thread_name.hpp"

namespace augrig::app {
namespace {

// The window, or none (no display, or it failed to open: then the run goes on headless and says so).
std::unique_ptr<Display> open_display(const Pipeline& pipeline, bool want_window,
                                      const std::string& screenshot_dir, std::ostream& out,
                                      std::ostream& err) {
  if (!want_window || !display_present()) return nullptr;
  DisplayOptions dopt;
  dopt.screenshot_dir = screenshot_dir;
  dopt.receiver_model = pipeline.parts().models.receiver_model;
  auto d = Display::create(dopt);
  if (!d) {
    err << "augrig: no window: " << user_message(d.error()) << "; running headless\n";
    return nullptr;
  }
  out << "live display open (F1 lists the keys)\n";
  return std::move(*d);
}

// "PATH (framebuffer WxH; left view x,y,w,h; right view ...; hud ...; pair N)": where a test
// finds the views in a screenshot.
std::string screenshot_line(const std::string& shot, const DisplayLayout& L, std::uint64_t pair) {
  std::ostringstream line;
  auto rect = [&](const PixelRect& r) { line << r.x << "," << r.y << "," << r.w << "," << r.h; };
  line << shot << " (framebuffer " << L.framebuffer_w << "x" << L.framebuffer_h << "; left view ";
  rect(L.views[0]);
  line << "; right view ";
  rect(L.views[1]);
  line << "; hud ";
  rect(L.hud);
  line << "; pair " << pair << ")";
  return line.str();
}

// The window's commands for the pipeline; closing the window quits.
PipelineCommands pipeline_commands(const DisplayCommands& c, bool window_open) {
  PipelineCommands pc;
  pc.quit = c.quit || !window_open;
  pc.toggle_pause = c.toggle_pause;
  pc.toggle_recording = c.toggle_recording;
  pc.boom_mode = c.boom_mode;
  pc.boom_nudge = c.boom_nudge;
  pc.steps = c.steps;
  pc.seek_frame = c.seek_frame;
  pc.rate = c.rate;
  return pc;
}

// The window's loop until the pipeline has finished: a frame at each new pair, else about 60 a
// second for input and the HUD; it never holds the pipeline. Returns the screenshots' lines.
std::vector<std::string> window_loop(Display& display, LiveView& view, const Rig& rig,
                                     std::uint64_t screenshot_at) {
  std::vector<std::string> screenshots;
  LiveView::Shown shown;
  // --screenshot-at N: one screenshot once the N-th pair is shown (written by the next frame()).
  bool shot_requested = false, shot_written = false;
  int frames_after_end = 0;
  for (bool last = false;;) {
    last = view.finished();
    const TimestampNs new_mid_host_ns = view.take_newest(shown);
    DisplayInput in;
    if (shown.id) in = display_input(shown.result, rig, shown.scene, shown.id);
    // The HUD from the pipeline, with the occlusion of the very pair shown (display_input's).
    const std::optional<OcclusionStats> shown_occlusion = in.hud.occlusion;
    in.hud = view.hud();
    if (shown.id) in.hud.occlusion = shown_occlusion;
    in.playback = view.playback();
    in.rig = &rig;
    if (screenshot_at && !shot_requested && shown.id >= screenshot_at) {
      display.request_screenshot();
      shot_requested = true;
    }
    const bool open = display.frame(in);
    view.drawn(new_mid_host_ns);  // drawn and swapped: on its way to the screen
    const DisplayCommands c = display.poll_commands();
    for (const std::string& shot : c.screenshots) {
      screenshots.push_back(screenshot_line(shot, display.layout(), shown.id));
      shot_written = true;
    }
    // The pipeline stopped: one more frame when a requested screenshot is still to be written.
    if (last && (!shot_requested || shot_written || ++frames_after_end > 10)) break;
    view.post(pipeline_commands(c, open));
    // Until the next pair is handed over (drawn at once: the latency to the screen is the
    // draw's), or 16 ms for input and the HUD.
    view.wait_newer(shown.id, std::chrono::milliseconds(16));
  }
  return screenshots;
}

// The pipeline on a worker, the window's loop here until it finishes; an exception on the worker
// is carried here, after the window closed.
Expected<PipelineReport> run_with_window(Pipeline& pipeline, std::unique_ptr<Display> display,
                                         std::ostream& out, std::ostream& err, std::uint64_t screenshot_at) {
  const std::shared_ptr<LiveView> view = pipeline.parts().view;
  Expected<PipelineReport> result = make_error("run_pipeline(): the pipeline did not run");
  std::optional<std::string> internal;
  std::thread worker([&] {
    set_thread_name("augrig-pipe");
    try {
      result = pipeline.run(out, err);
    } catch (const std::exception& e) {
      internal = e.what();
    }
    view->finish();
  });
  const std::vector<std::string> screenshots = window_loop(*display, *view, pipeline.rig(), screenshot_at);
  worker.join();
  display.reset();
  if (internal) runtime_error("internal error: " + *internal);
  for (const std::string& shot : screenshots) out << "screenshot " << shot << "\n";
  if (screenshot_at && screenshots.empty())
    err << "augrig: no screenshot: fewer than " << screenshot_at << " pairs were shown\n";
  return result;
}

}  // namespace

PipelineReport run_pipeline(Pipeline& pipeline, bool want_window, const std::string& screenshot_dir,
                            std::ostream& out, std::ostream& err, std::uint64_t screenshot_at) {
  std::unique_ptr<Display> display = open_display(pipeline, want_window, screenshot_dir, out, err);
  PipelineReport report =
      unwrap(display ? run_with_window(pipeline, std::move(display), out, err, screenshot_at)
                     : pipeline.run(out, err));
  pipeline.print_summary(report, out);
  return report;
}

}  // namespace augrig::app
