// The raster backends' registry: which backend each Rasterizer gets.
#include "render/backends/raster_backend.hpp"

#include <string>

#include <gtest/gtest.h>

#include "tests/support/gl_test.hpp"

namespace augrig {
namespace {

class RasterBackendRegistry : public test::GlTest {};

Rasterizer kind_for(Rasterizer r, ReceiverDraw draw = ReceiverDraw::kMaskOnly) {
  AugmentOptions opt;
  opt.rasterizer = r;
  opt.receiver_draw = draw;
  auto backend = raster_backends::make_raster_backend(opt);
  EXPECT_TRUE(backend) << backend.error().message;
  return backend ? (*backend)->kind() : Rasterizer::kAuto;
}

TEST_F(RasterBackendRegistry, NamedBackends) {
  EXPECT_EQ(kind_for(Rasterizer::kCpu), Rasterizer::kCpu);
  EXPECT_EQ(kind_for(Rasterizer::kOpenGl), Rasterizer::kOpenGl);
}

TEST_F(RasterBackendRegistry, OverlaysAlwaysUseOpenGl) {
  EXPECT_EQ(kind_for(Rasterizer::kCpu, ReceiverDraw::kWireframe), Rasterizer::kOpenGl);
  EXPECT_EQ(kind_for(Rasterizer::kAuto, ReceiverDraw::kTranslucent), Rasterizer::kOpenGl);
}

TEST_F(RasterBackendRegistry, AutoPicksTheCpuOnASoftwareGl) {
  const std::string renderer = context()->renderer();
  const bool software = renderer.find("llvmpipe") != std::string::npos ||
                        renderer.find("softpipe") != std::string::npos ||
                        renderer.find("swrast") != std::string::npos;
  EXPECT_EQ(kind_for(Rasterizer::kAuto), software ? Rasterizer::kCpu : Rasterizer::kOpenGl) << renderer;
}

}  // namespace
}  // namespace augrig
