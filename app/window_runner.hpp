// window_runner: runs a configured pipeline to its end, headless or with the live window, for
// every command that shows one (run, demo, replay, evaluate, augment). With a window, the window
// runs on this thread (GLFW wants the main thread) and the pipeline on a worker; they talk only
// through the pipeline's LiveView mailbox: the newest augmented pair one way, the user's commands
// (pause, step, seek, rate, quit, boom) the other.
#pragma once

#include <cstdint>
#include <ostream>
#include <string>

#include "pipeline/pipeline.hpp"

namespace augrig::app {

// Runs `pipeline` to its end, with the live window when `want_window` and a display is present
// (else headless, saying why when the window could not open); prints the summary; returns the
// report (the pipeline's errors become CommandErrors). `screenshot_at` N > 0: a screenshot into
// `screenshot_dir` once the N-th pair is shown, printed as "screenshot PATH (framebuffer WxH;
// left view x,y,w,h; right view ...; hud ...; pair N)".
pipeline::PipelineReport run_pipeline(pipeline::Pipeline& pipeline, bool want_window,
                                      const std::string& screenshot_dir, std::ostream& out, std::ostream& err,
                                      std::uint64_t screenshot_at = 0);

}  // namespace augrig::app
