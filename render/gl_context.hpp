// GlContext: an OpenGL 3.3+ core context, created by one of the backends in render/backends/
// (one file each): EGL headless (Mesa surfaceless, or the NVIDIA EGL device platform) and a GLFW
// window. create_gl_context() picks one and logs the backend and GL_RENDERER chosen.
#pragma once

#include <memory>
#include <string>

#include "core/expected.hpp"

struct GLFWwindow;

namespace augrig {

enum class GlBackend { kAuto, kEglHeadless, kGlfwWindow };

struct GlContextOptions {
  int window_width = 1280;  // GLFW only
  int window_height = 720;
  std::string window_title = "augrig";
  bool visible = true;  // GLFW only
  bool debug = false;   // request a debug context and log GL errors
};

class GlContext {
 public:
  virtual ~GlContext() = default;
  virtual const char* backend_name() const = 0;  // "egl-surfaceless", "egl-device", "glfw"
  virtual void make_current() = 0;
  virtual GLFWwindow* window() { return nullptr; }  // non-null for the GLFW backend
  std::string renderer() const;                     // GL_RENDERER
  std::string version() const;                      // GL_VERSION
};

// kAuto: EGL headless. Logs "GlContext: <backend>, <GL_RENDERER>, <GL_VERSION>" to stderr.
Expected<std::unique_ptr<GlContext>> create_gl_context(GlBackend backend,
                                                       const GlContextOptions& options = {});

// Backend factories, defined in render/backends/gl_context_*.cpp.
Expected<std::unique_ptr<GlContext>> create_egl_context(const GlContextOptions& options);
Expected<std::unique_ptr<GlContext>> create_glfw_context(const GlContextOptions& options);

}  // namespace augrig
