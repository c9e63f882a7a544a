// The OpenGL raster backend on a small scene (Mesa llvmpipe here, headless): ids packed as the
// augmenter reads them, the boom depth-tested against the receiver, its colour read back, and
// the same ids as the CPU backend away from the triangles' edges.
#include <gtest/gtest.h>

#include "render/backends/raster_backend.hpp"
#include "tests/render/backends/raster_test_scene.hpp"
#include "tests/support/gl_test.hpp"

namespace augrig {
namespace {

using raster_backends::kDrawShift;

class GlRaster : public test::GlTest {};

TEST_F(GlRaster, DrawsIdsAndColourWithTheBoomInFront) {
  test::RasterScene s;
  AugmentOptions opt;
  auto backend = raster_backends::make_gl_raster(opt);
  EXPECT_EQ(backend->kind(), Rasterizer::kOpenGl);
  EXPECT_FALSE(backend->concurrent_views());
  EXPECT_FALSE(backend->shades_per_pixel());
  ASSERT_TRUE(backend->init(s.draws, {&s.view}));
  ASSERT_EQ(s.view.boom_rgba.size(), 64u * 48u * 4u);
  EXPECT_TRUE(s.view.recv_rgba.empty());  // no overlay
  backend->draw(s.view, s.frame(), s.timings);
  ASSERT_TRUE(backend->errors());
  EXPECT_EQ(s.boom_id(31, 23), 1u << kDrawShift);
  EXPECT_EQ(s.recv_id(31, 23) >> kDrawShift, 2u);
  EXPECT_EQ(s.boom_id(1, 1), 0u);
  EXPECT_EQ(s.recv_id(1, 1) >> kDrawShift, 2u);
  EXPECT_GT(s.view.boom_rgba[(23 * 64 + 31) * 4], 0);  // the boom's shaded colour
  backend->clear(s.view);
  for (std::size_t i = 0; i < s.view.boom_ids.size(); ++i)
    ASSERT_EQ(s.view.boom_ids[i] | s.view.recv_ids[i], 0u);
}

TEST_F(GlRaster, OverlaysGetTheReceiversColour) {
  test::RasterScene s;
  AugmentOptions opt;
  opt.receiver_draw = ReceiverDraw::kTranslucent;
  auto backend = raster_backends::make_gl_raster(opt);
  ASSERT_TRUE(backend->init(s.draws, {&s.view}));
  ASSERT_EQ(s.view.recv_rgba.size(), 64u * 48u * 4u);
  backend->draw(s.view, s.frame(), s.timings);
  EXPECT_GT(s.view.recv_rgba[(1 * 64 + 1) * 4 + 3], 0);
}

TEST_F(GlRaster, SameIdsAsTheCpuBackendAwayFromEdges) {
  test::RasterScene gl_scene, cpu_scene;
  auto gl = raster_backends::make_gl_raster(AugmentOptions{});
  auto cpu = raster_backends::make_cpu_raster();
  ASSERT_TRUE(gl->init(gl_scene.draws, {&gl_scene.view}));
  ASSERT_TRUE(cpu->init(cpu_scene.draws, {&cpu_scene.view}));
  gl->draw(gl_scene.view, gl_scene.frame(), gl_scene.timings);
  cpu->draw(cpu_scene.view, cpu_scene.frame(), cpu_scene.timings);
  int compared = 0;
  for (int y = 1; y < 47; ++y)
    for (int x = 1; x < 63; ++x) {
      bool interior = true;  // the CPU's 3x3 neighbourhood holds one boom id and one receiver id
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
          interior = interior && cpu_scene.boom_id(x + dx, y + dy) == cpu_scene.boom_id(x, y) &&
                     cpu_scene.recv_id(x + dx, y + dy) == cpu_scene.recv_id(x, y);
      if (!interior) continue;
      ++compared;
      ASSERT_EQ(gl_scene.boom_id(x, y), cpu_scene.boom_id(x, y)) << x << "," << y;
      ASSERT_EQ(gl_scene.recv_id(x, y), cpu_scene.recv_id(x, y)) << x << "," << y;
    }
  EXPECT_GT(compared, 2000);
}

}  // namespace
}  // namespace augrig
