// GLFW window backend: an OpenGL 3.3+ core context with a window (needs a display; under CI use
// xvfb-run). Used by the real-time display.
#include <epoxy/gl.h>
// epoxy must come first: it replaces the system GL header GLFW would include.
#include <chrono>
#include <cstdlib>
#include <mutex>
#include <string>
#include <thread>

#include <GLFW/glfw3.h>

#include "render/gl_context.hpp"

namespace augrig {

namespace {

std::string g_glfw_error;
void on_glfw_error(int code, const char* description) {
  g_glfw_error = "GLFW error " + std::to_string(code) + ": " + (description ? description : "?");
}

class GlfwContext final : public GlContext {
 public:
  explicit GlfwContext(GLFWwindow* w) : window_(w) {}
  ~GlfwContext() override {
    glfwDestroyWindow(window_);
    glfwTerminate();
  }
  const char* backend_name() const override { return "glfw"; }
  void make_current() override { glfwMakeContextCurrent(window_); }
  GLFWwindow* window() override { return window_; }

 private:
  GLFWwindow* window_;
};

}  // namespace

Expected<std::unique_ptr<GlContext>> create_glfw_context(const GlContextOptions& options) {
  glfwSetErrorCallback(on_glfw_error);
  // A display that is there but refuses a connection for a moment (its server still starting,
  // or closing the previous client) is retried briefly; with no DISPLAY at all it fails at once.
  bool ok = glfwInit() == GLFW_TRUE;
  for (int attempt = 1; !ok && std::getenv("DISPLAY") && attempt <= 4; ++attempt) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100 * attempt));
    ok = glfwInit() == GLFW_TRUE;
  }
  if (!ok)
    return make_error(
        "render::create_glfw_context(): glfwInit failed (no display? run under xvfb-run, or use "
        "the EGL headless backend): ",
        g_glfw_error);
  GLFWwindow* w = nullptr;
  for (auto [maj, min] : {std::pair{4, 5}, std::pair{3, 3}}) {
    glfwDefaultWindowHints();
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, maj);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, min);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_OPENGL_DEBUG_CONTEXT, options.debug ? GLFW_TRUE : GLFW_FALSE);
    glfwWindowHint(GLFW_VISIBLE, options.visible ? GLFW_TRUE : GLFW_FALSE);
    glfwWindowHint(GLFW_SCALE_TO_MONITOR, GLFW_TRUE);  // HiDPI: window size in screen coordinates
    // No depth or stencil in the window itself: what needs depth (the augmenter, the world view)
    // renders into framebuffers of its own, and a window without them lets llvmpipe skip keeping
    // stencil bits on every clear (0.5 to 2 ms a redraw at 1600x1000).
    glfwWindowHint(GLFW_DEPTH_BITS, 0);
    glfwWindowHint(GLFW_STENCIL_BITS, 0);
    w = glfwCreateWindow(options.window_width, options.window_height, options.window_title.c_str(), nullptr,
                         nullptr);
    if (w) break;
  }
  if (!w) {
    glfwTerminate();
    return make_error("render::create_glfw_context(): cannot create an OpenGL 3.3 core window: ",
                      g_glfw_error);
  }
  glfwMakeContextCurrent(w);
  glfwSwapInterval(1);
  return std::unique_ptr<GlContext>(new GlfwContext(w));
}

}  // namespace augrig
