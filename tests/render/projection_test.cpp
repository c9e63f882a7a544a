// Tests for render/projection.hpp's virtual pinhole: an identity grid without distortion, a grid
// that covers every valid ray with distortion, and an Error, not a negative or overflowing size,
// when no pixel has a ray or the virtual image would be absurdly large.
#include "render/projection.hpp"

#include <cmath>
#include <limits>
#include <string>

#include <gtest/gtest.h>

namespace augrig {
namespace {

CameraModel pinhole() {
  CameraModel m;
  m.width_px = 64, m.height_px = 48;
  m.fx_px = m.fy_px = 50;
  m.cx_px = 31.5, m.cy_px = 23.5;
  return m;
}

TEST(VirtualPinhole, WithoutDistortionTheGridIsTheCamerasOwn) {
  const auto vp = make_virtual_pinhole(pinhole());
  ASSERT_TRUE(vp) << vp.error().message;
  EXPECT_TRUE(vp->identity);
  EXPECT_EQ(vp->width, 64);
  EXPECT_EQ(vp->height, 48);
  EXPECT_FLOAT_EQ(vp->ray_xy[0].x(), static_cast<float>(-31.5 / 50));
}

TEST(VirtualPinhole, WithDistortionEveryValidRayFallsInside) {
  CameraModel m = pinhole();
  m.distortion = DistortionModel::kRadTan;
  m.coeffs = {-0.3, 0.1, 0, 0, 0};
  const auto vp = make_virtual_pinhole(m, 1.0, true, "left");
  ASSERT_TRUE(vp) << vp.error().message;
  EXPECT_FALSE(vp->identity);
  EXPECT_GE(vp->width, 64);
  EXPECT_GE(vp->height, 48);
  for (const Eigen::Vector2f& r : vp->ray_xy) {
    ASSERT_TRUE(std::isfinite(r.x()));
    const Eigen::Vector2d p = vp->to_virtual(r.cast<double>());
    EXPECT_GE(p.x(), 2.0);
    EXPECT_LE(p.x(), vp->width - 3.0);
    EXPECT_GE(p.y(), 2.0);
    EXPECT_LE(p.y(), vp->height - 3.0);
  }
}

// Distortion that folds back within 0.012 (normalised) of the principal point, which lies far
// outside the image: no pixel has a ray. The extents stayed at +-1e9 and the width came out
// negative (or, converted from -1e12, undefined).
TEST(VirtualPinhole, NoPixelWithARayIsAnError) {
  CameraModel m = pinhole();
  m.distortion = DistortionModel::kRadTan;
  m.coeffs = {-1000, 0, 0, 0, 0};
  m.cx_px = -60, m.cy_px = -40;
  const auto vp = make_virtual_pinhole(m, 1.0, false, "left");
  ASSERT_FALSE(vp);
  EXPECT_EQ(
      vp.error().message,
      "render::make_virtual_pinhole(): camera 'left': no pixel of the 64x48 image undistorts to a ray in "
      "front of the camera (within 80 deg of its axis): check the distortion coefficients");
}

// A virtual image beyond kMaxVirtualSidePx on a side is refused; beyond int it was undefined.
TEST(VirtualPinhole, AbsurdSizesAreAnError) {
  CameraModel m = pinhole();
  m.distortion = DistortionModel::kRadTan;  // not the identity shortcut
  for (const double scale : {1e3, 1e9, 1e300, std::numeric_limits<double>::quiet_NaN(), -1.0}) {
    const auto vp = make_virtual_pinhole(m, scale, false, "right");
    ASSERT_FALSE(vp) << scale;
    EXPECT_NE(vp.error().message.find("render::make_virtual_pinhole(): camera 'right': the undistorted image "
                                      "would need "),
              std::string::npos)
        << vp.error().message;
    EXPECT_NE(vp.error().message.find("check the focal lengths and the distortion coefficients"),
              std::string::npos)
        << vp.error().message;
  }
  m.width_px = 0;
  const auto none = make_virtual_pinhole(m);
  ASSERT_FALSE(none);
  EXPECT_EQ(none.error().message, "render::make_virtual_pinhole(): camera '': no image size (0x48)");
}

}  // namespace
}  // namespace augrig
