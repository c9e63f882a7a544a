// The CPU raster backend on a small scene: ids packed as the augmenter reads them, the boom
// depth-tested against the receiver, the blocks it wrote marked, and clear() undoing a frame.
#include <gtest/gtest.h>

#include "render/backends/raster_backend.hpp"
#include "tests/render/backends/raster_test_scene.hpp"

namespace augrig {
namespace {

using raster_backends::kBlockShift;
using raster_backends::kBoomBlock;
using raster_backends::kDrawShift;
using raster_backends::kReceiverBlock;

TEST(CpuRaster, DrawsIdsWithTheBoomInFrontAndMarksItsBlocks) {
  test::RasterScene s;
  auto backend = raster_backends::make_cpu_raster();
  EXPECT_EQ(backend->kind(), Rasterizer::kCpu);
  EXPECT_TRUE(backend->concurrent_views());
  EXPECT_TRUE(backend->shades_per_pixel());
  ASSERT_TRUE(backend->init(s.draws, {&s.view}));
  ASSERT_EQ(s.view.shading.size(), 3u);  // one per triangle of every draw item
  backend->draw(s.view, s.frame(), s.timings);
  // The view's centre: the boom (draw 1, triangle 0) in front of the receiver (draw 2).
  EXPECT_EQ(s.boom_id(31, 23), 1u << kDrawShift);
  EXPECT_EQ(s.recv_id(31, 23) >> kDrawShift, 2u);
  // A corner: the receiver alone.
  EXPECT_EQ(s.boom_id(1, 1), 0u);
  EXPECT_EQ(s.recv_id(1, 1) >> kDrawShift, 2u);
  // Every written sample lies in a block marked for its image.
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) {
      const std::uint8_t mark = s.view.occupied[(y >> kBlockShift) * s.view.blocks_x + (x >> kBlockShift)];
      if (s.boom_id(x, y)) {
        EXPECT_TRUE(mark & kBoomBlock) << x << "," << y;
      }
      if (s.recv_id(x, y)) {
        EXPECT_TRUE(mark & kReceiverBlock) << x << "," << y;
      }
    }
  // The boom is plain grey under the fixed light: a positive shade at the centre.
  const auto c = detail::shade(s.view.shading[0], 0.0f, 0.0f);
  EXPECT_GT(c[0], 0.f);
}

TEST(CpuRaster, ClearZeroesWhatTheLastDrawWrote) {
  test::RasterScene s;
  auto backend = raster_backends::make_cpu_raster();
  ASSERT_TRUE(backend->init(s.draws, {&s.view}));
  backend->draw(s.view, s.frame(), s.timings);
  backend->clear(s.view);
  for (std::size_t i = 0; i < s.view.boom_ids.size(); ++i) {
    ASSERT_EQ(s.view.boom_ids[i], 0u) << i;
    ASSERT_EQ(s.view.recv_ids[i], 0u) << i;
  }
  // A second frame draws the same ids again (its depth was cleared too).
  backend->draw(s.view, s.frame(), s.timings);
  EXPECT_EQ(s.boom_id(31, 23), 1u << kDrawShift);
}

TEST(CpuRaster, DrawsNothingWithoutBoxes) {
  test::RasterScene s;
  auto backend = raster_backends::make_cpu_raster();
  ASSERT_TRUE(backend->init(s.draws, {&s.view}));
  raster_backends::RasterFrame f = s.frame();
  s.view.boom_vboxes.clear(), s.view.recv_vboxes.clear();
  backend->draw(s.view, f, s.timings);
  for (std::size_t i = 0; i < s.view.boom_ids.size(); ++i)
    ASSERT_EQ(s.view.boom_ids[i] | s.view.recv_ids[i], 0u);
}

}  // namespace
}  // namespace augrig
