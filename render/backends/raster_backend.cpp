// The raster backends' registry (render/backends/raster_backend.hpp): which one draws.
#include "render/backends/raster_backend.hpp"

#include <string>

#include <epoxy/gl.h>

namespace augrig::raster_backends {

namespace {

// A software GL pays per pixel for each attachment it clears, writes and reads back: there the
// CPU backend, which writes one id and one depth per covered sample, is faster.
bool software_gl() {
  const auto* name = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  const std::string renderer = name ? name : "";
  return renderer.find("llvmpipe") != std::string::npos || renderer.find("softpipe") != std::string::npos ||
         renderer.find("swrast") != std::string::npos ||
         renderer.find("Software Rasterizer") != std::string::npos;
}

}  // namespace

Expected<std::unique_ptr<RasterBackend>> make_raster_backend(const AugmentOptions& options) {
  // The validation overlays draw the receiver's colour: OpenGL only.
  if (options.receiver_draw != ReceiverDraw::kMaskOnly) return make_gl_raster(options);
  switch (options.rasterizer) {
    case Rasterizer::kAuto:
      if (software_gl()) return make_cpu_raster();
      return make_gl_raster(options);
    case Rasterizer::kOpenGl:
      return make_gl_raster(options);
    case Rasterizer::kCpu:
      return make_cpu_raster();
  }
  return make_error("make_raster_backend(): unknown rasteriser ", static_cast<int>(options.rasterizer));
}

}  // namespace augrig::raster_backends
