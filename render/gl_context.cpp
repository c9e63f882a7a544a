// Backend selection and the backend-independent parts of GlContext.
#include "render/gl_context.hpp"

#include <cstdio>

#include <epoxy/gl.h>

namespace augrig {

namespace {
std::string gl_string(GLenum name) {
  const auto* s = reinterpret_cast<const char*>(glGetString(name));
  return s ? s : "?";
}
}  // namespace

std::string GlContext::renderer() const {
  return gl_string(GL_RENDERER);
}
std::string GlContext::version() const {
  return gl_string(GL_VERSION);
}

Expected<std::unique_ptr<GlContext>> create_gl_context(GlBackend backend, const GlContextOptions& options) {
  auto ctx = backend == GlBackend::kGlfwWindow ? create_glfw_context(options) : create_egl_context(options);
  if (!ctx) return ctx.error();
  // GL 3.3 core is the floor: the renderer uses MRT, integer ids packed in RGBA8 and VAOs.
  if (epoxy_gl_version() < 33) {
    return make_error("render::create_gl_context(): ", (*ctx)->backend_name(), " gave OpenGL ",
                      (*ctx)->version(), ", need 3.3 core or later");
  }
  std::fprintf(stderr, "GlContext: %s, %s, %s\n", (*ctx)->backend_name(), (*ctx)->renderer().c_str(),
               (*ctx)->version().c_str());
  return ctx;
}

}  // namespace augrig
