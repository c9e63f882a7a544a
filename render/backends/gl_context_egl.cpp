// EGL headless backend: no display, no window. Uses the NVIDIA EGL device platform when an
// NVIDIA device is present, else Mesa's surfaceless platform (llvmpipe on CPU-only machines).
// AUGRIG_EGL_PLATFORM=device|surfaceless forces one.
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include <epoxy/egl.h>
#include <epoxy/gl.h>

#include "render/gl_context.hpp"

namespace augrig {

namespace {

class EglContext final : public GlContext {
 public:
  EglContext(EGLDisplay dpy, EGLContext ctx, const char* name) : dpy_(dpy), ctx_(ctx), name_(name) {}
  ~EglContext() override {
    eglMakeCurrent(dpy_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(dpy_, ctx_);
    eglTerminate(dpy_);
  }
  const char* backend_name() const override { return name_; }
  void make_current() override { eglMakeCurrent(dpy_, EGL_NO_SURFACE, EGL_NO_SURFACE, ctx_); }

 private:
  EGLDisplay dpy_;
  EGLContext ctx_;
  const char* name_;
};

bool has_extension(const char* list, const char* ext) {
  if (!list) return false;
  const std::size_t n = std::strlen(ext);
  for (const char* p = std::strstr(list, ext); p; p = std::strstr(p + 1, ext))
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  return false;
}

// First EGL device that is an NVIDIA GPU (EGL_NV_device_cuda), or EGL_NO_DEVICE_EXT.
EGLDeviceEXT find_nvidia_device() {
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (!has_extension(client, "EGL_EXT_device_enumeration") && !has_extension(client, "EGL_EXT_device_base"))
    return EGL_NO_DEVICE_EXT;
  EGLint n = 0;
  if (!eglQueryDevicesEXT(0, nullptr, &n) || n <= 0) return EGL_NO_DEVICE_EXT;
  std::vector<EGLDeviceEXT> devices(static_cast<std::size_t>(n));
  eglQueryDevicesEXT(n, devices.data(), &n);
  for (EGLDeviceEXT d : devices)
    if (has_extension(eglQueryDeviceStringEXT(d, EGL_EXTENSIONS), "EGL_NV_device_cuda")) return d;
  return EGL_NO_DEVICE_EXT;
}

}  // namespace

Expected<std::unique_ptr<GlContext>> create_egl_context(const GlContextOptions& options) {
  const char* forced = std::getenv("AUGRIG_EGL_PLATFORM");
  const std::string want = forced ? forced : "";
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);

  EGLDisplay dpy = EGL_NO_DISPLAY;
  const char* name = "";
  if (want != "surfaceless") {
    if (EGLDeviceEXT dev = find_nvidia_device(); dev != EGL_NO_DEVICE_EXT) {
      dpy = eglGetPlatformDisplayEXT(EGL_PLATFORM_DEVICE_EXT, dev, nullptr);
      name = "egl-device";
    } else if (want == "device") {
      return make_error(
          "render::create_egl_context(): AUGRIG_EGL_PLATFORM=device but no NVIDIA EGL device found");
    }
  }
  if (dpy == EGL_NO_DISPLAY) {
    if (!has_extension(client, "EGL_MESA_platform_surfaceless"))
      return make_error(
          "render::create_egl_context(): EGL lacks EGL_MESA_platform_surfaceless and no GPU device; "
          "install libegl1 and libgl1-mesa-dri (scripts/install-deps.sh)");
    dpy = eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    name = "egl-surfaceless";
  }
  EGLint major = 0, minor = 0;
  if (dpy == EGL_NO_DISPLAY || !eglInitialize(dpy, &major, &minor))
    return make_error("render::create_egl_context(): eglInitialize failed on ", name, " (EGL error 0x",
                      std::to_string(eglGetError()), ")");
  if (!eglBindAPI(EGL_OPENGL_API)) {
    eglTerminate(dpy);
    return make_error("render::create_egl_context(): eglBindAPI(EGL_OPENGL_API) failed on ", name);
  }
  const EGLint config_attribs[] = {EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT,
                                   EGL_NONE};
  EGLConfig config = nullptr;
  EGLint n_configs = 0;
  // Surfaceless contexts need no surface type; retry without it if the platform offers none.
  if (!eglChooseConfig(dpy, config_attribs, &config, 1, &n_configs) || n_configs == 0) {
    const EGLint any[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    if (!eglChooseConfig(dpy, any, &config, 1, &n_configs) || n_configs == 0) {
      eglTerminate(dpy);
      return make_error("render::create_egl_context(): no OpenGL-capable EGL config on ", name);
    }
  }
  // Prefer 4.5 core (glClipControl for reversed-Z), fall back to 3.3 core.
  EGLContext ctx = EGL_NO_CONTEXT;
  for (auto [maj, min] : {std::pair{4, 5}, std::pair{3, 3}}) {
    const EGLint ctx_attribs[] = {EGL_CONTEXT_MAJOR_VERSION,
                                  maj,
                                  EGL_CONTEXT_MINOR_VERSION,
                                  min,
                                  EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                  EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                  EGL_CONTEXT_OPENGL_DEBUG,
                                  options.debug ? EGL_TRUE : EGL_FALSE,
                                  EGL_NONE};
    ctx = eglCreateContext(dpy, config, EGL_NO_CONTEXT, ctx_attribs);
    if (ctx != EGL_NO_CONTEXT) break;
  }
  if (ctx == EGL_NO_CONTEXT) {
    eglTerminate(dpy);
    return make_error("render::create_egl_context(): cannot create an OpenGL 3.3 core context on ", name);
  }
  if (!eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, ctx)) {
    eglDestroyContext(dpy, ctx);
    eglTerminate(dpy);
    return make_error("render::create_egl_context(): eglMakeCurrent without a surface failed on ", name);
  }
  return std::unique_ptr<GlContext>(new EglContext(dpy, ctx, name));
}

}  // namespace augrig
