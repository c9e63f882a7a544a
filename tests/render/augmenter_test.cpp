// The augmenter against independent oracles: OpenCV's projectPoints for projection and
// distortion, a CPU ray caster (tests/support/ray_caster.hpp) for the masks, brute-force
// comparison with the raw image for untouched pixels. Each runs with both rasterisers (OpenGL
// and render/soft_raster.hpp), and the two are compared with each other.
#include "render/augmenter.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <memory>
#include <random>
#include <string>
#include <tuple>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>

#include "render/gl_context.hpp"
#include "tests/support/gl_test.hpp"
#include "tests/support/ray_caster.hpp"
#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

// The paper's rig with a strongly distorting lens and an off-centre principal point.
Rig distorted_rig() {
  Rig rig = Rig::paper_default();
  for (RigCamera& c : rig.cameras) {
    c.model.distortion = DistortionModel::kRadTan;
    c.model.coeffs = {-0.28, 0.12, 8e-4, -6e-4, -0.02};
    c.model.cx_px += 12.3;
    c.model.cy_px -= 8.7;
    c.model.fy_px *= 0.997;
  }
  return rig;
}

SceneState contact_scene(const Rig& rig, const BoomModel& boom, const Eigen::Vector3d& receptacle_m,
                         BoomArticulation a) {
  return scene_at_contact(rig, boom.dims, receptacle_m, a);
}

class AugmenterTest : public test::GlTest {};

// Every property below must hold whichever rasteriser produced the virtual image.
class RasterizerTest : public AugmenterTest, public ::testing::WithParamInterface<Rasterizer> {
 protected:
  AugmentOptions options() const {
    AugmentOptions opt;
    opt.rasterizer = GetParam();
    return opt;
  }
};
std::string raster_name(const ::testing::TestParamInfo<Rasterizer>& info) {
  return to_string(info.param);
}

// Writes a diff image (red: ours only, green: oracle only) when masks disagree.
void write_mask_diff(const std::string& name, const Image& ours, const Image& oracle) {
  static const std::string dir = test::output_dir("augmenter");
  cv::Mat diff(ours.height(), ours.width(), CV_8UC3, cv::Scalar(0, 0, 0));
  for (int y = 0; y < ours.height(); ++y)
    for (int x = 0; x < ours.width(); ++x) {
      const int a = ours.row(y)[x], b = oracle.row(y)[x];
      auto& px = diff.at<cv::Vec3b>(y, x);
      px = cv::Vec3b(static_cast<uchar>(40 * b), static_cast<uchar>(40 * a), 0);
      if (a != b) px = (a & ~b) ? cv::Vec3b(0, 0, 255) : cv::Vec3b(0, 255, 0);
    }
  cv::imwrite(dir + "/" + name + "_mask_diff.png", diff);
}

class MaskOracleTest : public AugmenterTest,
                       public ::testing::WithParamInterface<std::tuple<bool, Rasterizer>> {};

// Distorted lens, and a pinhole lens (where anti-aliasing samples between pixel centres).
TEST_P(MaskOracleTest, MasksAgreeWithRayCasterAtPixelCentres) {
  const auto [distorted, raster] = GetParam();
  const Rig rig = distorted ? distorted_rig() : Rig::paper_default();
  AugmentOptions opt;
  opt.rasterizer = raster;
  auto aug = Augmenter::create(rig, opt);
  ASSERT_TRUE(aug) << aug.error().message;
  ASSERT_EQ((*aug)->rasterizer(), raster);
  Eigen::Vector3d receptacle;
  make_builtin_receiver(&receptacle);
  // Two articulations: a contact and a boom off to the side above the receiver.
  for (const BoomArticulation& a : {BoomArticulation{0.52, 0.03, 3.0}, BoomArticulation{0.40, -0.2, 1.0}}) {
    SceneState scene = contact_scene(rig, (*aug)->boom_model(), receptacle, a);
    if (a.extension_m < 2) scene.T_body_receiver.translation_m += Eigen::Vector3d(-1.5, 0.8, 1.2);
    StereoFrame sf;
    sf.left = test::gradient_frame(rig.left().model, PixelFormat::kRGB8, CameraId::kLeft);
    sf.right = test::gradient_frame(rig.right().model, PixelFormat::kRGB8, CameraId::kRight);
    StereoResult out;
    ASSERT_TRUE((*aug)->augment(sf, scene, out));

    for (int c = 0; c < 2; ++c) {
      const RigCamera& cam = rig.cameras[c];
      const Pose T_cam_body = cam.T_body_cam.inverse();
      const Pose T_body_boom = boom_pose(rig.boom.pivot_body_m, a);
      test::RayCaster boom, receiver;
      boom.add((*aug)->boom_model().fixed, T_cam_body * T_body_boom);
      boom.add((*aug)->boom_model().telescope, T_cam_body * T_body_boom * telescope_pose(a));
      receiver.add((*aug)->receiver_model(), T_cam_body * scene.T_body_receiver);
      const Image oracle = test::ray_cast_mask(cam.model, test::opencv_pixel_rays(cam.model), boom, receiver);
      const Image& ours = c == 0 ? out.left.mask : out.right.mask;

      std::int64_t disagree = 0, far_from_edge = 0, boom_px = 0, recv_px = 0;
      const int W = ours.width(), H = ours.height();
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
          const int o = oracle.row(y)[x];
          boom_px += (o & kMaskBoom) != 0;
          recv_px += (o & kMaskReceiver) != 0;
          if (ours.row(y)[x] == o) continue;
          ++disagree;
          // Within 1 px of a silhouette edge: the oracle changes value in the 3x3 neighbourhood.
          bool edge = false;
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              const int xx = std::clamp(x + dx, 0, W - 1), yy = std::clamp(y + dy, 0, H - 1);
              edge |= oracle.row(yy)[xx] != o;
            }
          far_from_edge += !edge;
        }
      const double agree = 1.0 - static_cast<double>(disagree) / (static_cast<double>(W) * H);
      std::printf(
          "camera %d: boom %lld px, receiver %lld px, disagree %lld (%.5f%% agree), far from edge %lld\n", c,
          static_cast<long long>(boom_px), static_cast<long long>(recv_px), static_cast<long long>(disagree),
          100 * agree, static_cast<long long>(far_from_edge));
      EXPECT_GT(boom_px, 10000) << "the scene must show the boom";
      EXPECT_GT(recv_px, 50000) << "the scene must show the receiver";
      EXPECT_GE(agree, 0.9999);
      EXPECT_EQ(far_from_edge, 0);
      if (agree < 0.9999 || far_from_edge)
        write_mask_diff(std::string(to_string(raster)) + "_scene" + std::to_string(a.extension_m < 2) +
                            "_camera" + std::to_string(c),
                        ours, oracle);
    }
  }
}

// A flat disc facing the camera, as a fan of `n` triangles, centred at `centre_cam` (camera frame).
Mesh disc(const Eigen::Vector3d& centre_cam, double radius_m, int n) {
  Mesh m;
  m.name = "marker";
  const Eigen::Vector3d z = -centre_cam.normalized();  // faces the camera
  const Eigen::Vector3d x = Eigen::Vector3d::UnitY().cross(z).normalized();
  const Eigen::Vector3d y = z.cross(x);
  m.positions_m.push_back(centre_cam.cast<float>());
  for (int i = 0; i < n; ++i) {
    const double a = 2 * M_PI * i / n;
    m.positions_m.push_back((centre_cam + radius_m * (std::cos(a) * x + std::sin(a) * y)).cast<float>());
  }
  for (int i = 0; i < n; ++i) {
    // Both windings: culling must not decide the test.
    m.indices.insert(m.indices.end(),
                     {0u, static_cast<std::uint32_t>(1 + i), static_cast<std::uint32_t>(1 + (i + 1) % n)});
  }
  m.normals.assign(m.positions_m.size(), z.cast<float>());
  return m;
}

INSTANTIATE_TEST_SUITE_P(Lenses, MaskOracleTest,
                         ::testing::Combine(::testing::Bool(),
                                            ::testing::Values(Rasterizer::kOpenGl, Rasterizer::kCpu)),
                         [](const auto& info) {
                           return std::string(std::get<0>(info.param) ? "radtan_" : "pinhole_") +
                                  to_string(std::get<1>(info.param));
                         });

INSTANTIATE_TEST_SUITE_P(Rasterizers, RasterizerTest,
                         ::testing::Values(Rasterizer::kOpenGl, Rasterizer::kCpu), raster_name);

TEST_P(RasterizerTest, ProjectionMatchesOpenCvProjectPoints) {
  Rig rig = distorted_rig();
  const RigCamera& cam = rig.left();
  // Markers all over the image (corners included), 8 to 30 m away, each a 64-gon of ~30 px radius.
  std::vector<Eigen::Vector3d> centres;
  for (double v : {0.06, 0.3, 0.5, 0.72, 0.93})
    for (double u : {0.05, 0.27, 0.5, 0.73, 0.95}) {
      const double depth = 8 + 22 * u * v;
      const auto xy = cam.model.undistort({u * cam.model.width_px, v * cam.model.height_px});
      ASSERT_TRUE(xy);
      centres.push_back(depth * Eigen::Vector3d(xy->x(), xy->y(), 1.0));
    }
  auto receiver = std::make_shared<Model>();
  const int kSides = 64;
  for (const auto& c : centres) receiver->meshes.push_back(disc(c, 0.028 * c.z(), kSides));
  AugmentOptions opt = options();
  opt.receiver_model = receiver;
  opt.stereo_classes = false;
  auto aug = Augmenter::create(rig, opt);
  ASSERT_TRUE(aug) << aug.error().message;
  SceneState scene;
  scene.boom = {0.35, 0, 0};
  scene.boom.azimuth_rad = 0.26;           // out of the way
  scene.T_body_receiver = cam.T_body_cam;  // marker coordinates are left-camera coordinates
  ViewResult out;
  ASSERT_TRUE((*aug)->augment_view(0, test::gradient_frame(cam.model, PixelFormat::kMono8, CameraId::kLeft),
                                   scene, out));

  const Eigen::Matrix3d K = cam.model.K();
  const cv::Matx33d Kcv(K(0, 0), K(0, 1), K(0, 2), K(1, 0), K(1, 1), K(1, 2), K(2, 0), K(2, 1), K(2, 2));
  const std::vector<double> D(cam.model.coeffs.begin(), cam.model.coeffs.end());
  double sum_sq = 0, worst = 0;
  for (std::size_t i = 0; i < centres.size(); ++i) {
    const Mesh& m = receiver->meshes[i];
    // Oracle: the projected outline (each straight 3D edge sampled densely, projected by OpenCV),
    // and the area centroid of that polygon.
    std::vector<cv::Point3d> outline;
    for (int k = 0; k < kSides; ++k) {
      const Eigen::Vector3d a = m.positions_m[1 + k].cast<double>(),
                            b = m.positions_m[1 + (k + 1) % kSides].cast<double>();
      for (int s = 0; s < 16; ++s) {
        const Eigen::Vector3d p = a + (b - a) * (s / 16.0);
        outline.emplace_back(p.x(), p.y(), p.z());
      }
    }
    std::vector<cv::Point2d> img;
    cv::projectPoints(outline, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), Kcv, D, img);
    double A = 0, cx = 0, cy = 0;
    for (std::size_t k = 0; k < img.size(); ++k) {
      const cv::Point2d& p = img[k];
      const cv::Point2d& q = img[(k + 1) % img.size()];
      const double cr = p.x * q.y - q.x * p.y;
      A += cr, cx += (p.x + q.x) * cr, cy += (p.y + q.y) * cr;
    }
    cx /= 3 * A, cy /= 3 * A;
    // Ours: centroid of the mask's pixel centres in a window around the oracle's centroid.
    double sx = 0, sy = 0, n = 0;
    const int r = 60;
    for (int y = std::max(0, static_cast<int>(cy) - r);
         y < std::min(cam.model.height_px, static_cast<int>(cy) + r); ++y)
      for (int x = std::max(0, static_cast<int>(cx) - r);
           x < std::min(cam.model.width_px, static_cast<int>(cx) + r); ++x)
        if (out.mask.row(y)[x] & kMaskReceiver) sx += x, sy += y, n += 1;
    ASSERT_GT(n, 500) << "marker " << i << " not rendered";
    const double err = std::hypot(sx / n - cx, sy / n - cy);
    // The mask's area should match the polygon's within the pixel quantisation of its edge.
    EXPECT_NEAR(n, std::abs(A) / 2, 0.02 * std::abs(A) / 2) << "marker " << i;
    sum_sq += err * err;
    worst = std::max(worst, err);
  }
  const double rms = std::sqrt(sum_sq / centres.size());
  std::printf("marker centroids vs cv::projectPoints: rms %.4f px, max %.4f px over %zu markers\n", rms,
              worst, centres.size());
  EXPECT_LE(rms, 0.05);
  EXPECT_LE(worst, 0.1);
}

TEST_P(RasterizerTest, UntouchedPixelsAreBitIdenticalInEveryFormat) {
  const Rig rig = distorted_rig();
  auto aug = Augmenter::create(rig, options());
  ASSERT_TRUE(aug) << aug.error().message;
  Eigen::Vector3d receptacle;
  make_builtin_receiver(&receptacle);
  const SceneState scene = contact_scene(rig, (*aug)->boom_model(), receptacle, {0.5, 0.05, 2.0});
  for (PixelFormat fmt : {PixelFormat::kRGB8, PixelFormat::kMono8, PixelFormat::kBayerRG8,
                          PixelFormat::kBayerGB8, PixelFormat::kRGBA8}) {
    SCOPED_TRACE(std::string(to_string(fmt)));
    StereoFrame sf;
    sf.left = test::gradient_frame(rig.left().model, fmt, CameraId::kLeft);
    sf.right = test::gradient_frame(rig.right().model, fmt, CameraId::kRight);
    StereoResult out;
    ASSERT_TRUE((*aug)->augment(sf, scene, out));
    for (int c = 0; c < 2; ++c) {
      const Image& raw = c == 0 ? sf.left.image : sf.right.image;
      const ViewResult& v = c == 0 ? out.left : out.right;
      ASSERT_EQ(v.augmented.format(), fmt);
      const int W = raw.width(), H = raw.height(), bpp = bytes_per_pixel(fmt);
      std::int64_t changed = 0, changed_far = 0, boom_unchanged = 0, boom_px = 0;
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
          const bool diff = std::memcmp(raw.row(y) + x * bpp, v.augmented.row(y) + x * bpp, bpp) != 0;
          bool near_boom = false;
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx)
              near_boom |=
                  (v.mask.row(std::clamp(y + dy, 0, H - 1))[std::clamp(x + dx, 0, W - 1)] & kMaskBoom) != 0;
          changed += diff;
          changed_far += diff && !near_boom;
          if (v.mask.row(y)[x] & kMaskBoom) {
            ++boom_px;
            // Interior boom pixels (all 8 neighbours boom) must carry the boom.
            bool interior = true;
            for (int dy = -1; dy <= 1; ++dy)
              for (int dx = -1; dx <= 1; ++dx)
                interior &=
                    (v.mask.row(std::clamp(y + dy, 0, H - 1))[std::clamp(x + dx, 0, W - 1)] & kMaskBoom) != 0;
            boom_unchanged += interior && !diff;
          }
        }
      EXPECT_GT(boom_px, 5000);
      EXPECT_EQ(changed_far, 0) << "pixels changed farther than 1 px from the boom";
      // Gradient backgrounds can coincide with the boom colour by chance, rarely.
      EXPECT_LT(boom_unchanged, boom_px / 100);
      EXPECT_GE(changed, boom_px - boom_px / 100);
    }
  }
}

// AugmentedOutput::kChangedBox: only the box is made, and it is the whole image's box exactly;
// outside the box the whole image is the raw image.
TEST_P(RasterizerTest, ChangedBoxOutputIsTheWholeImageInsideItsBox) {
  const Rig rig = distorted_rig();
  auto augmenters = test::whole_and_box_augmenters(rig, options());
  ASSERT_TRUE(augmenters) << augmenters.error().message;
  Augmenter &whole = *augmenters->whole, &box = *augmenters->box;
  Eigen::Vector3d receptacle;
  make_builtin_receiver(&receptacle);
  for (PixelFormat fmt : {PixelFormat::kRGB8, PixelFormat::kBayerGR8}) {
    StereoFrame sf;
    sf.left = test::gradient_frame(rig.left().model, fmt, CameraId::kLeft);
    sf.right = test::gradient_frame(rig.right().model, fmt, CameraId::kRight);
    StereoResult a, b;
    // Two scenes in a row: the box changes size between frames and its buffer is reused.
    for (const BoomArticulation art : {BoomArticulation{0.5, 0.05, 2.0}, BoomArticulation{0.6, -0.1, 4.0}}) {
      SCOPED_TRACE(std::string(to_string(fmt)) + " extension " + std::to_string(art.extension_m));
      const SceneState scene = contact_scene(rig, whole.boom_model(), receptacle, art);
      ASSERT_TRUE(whole.augment(sf, scene, a));
      ASSERT_TRUE(box.augment(sf, scene, b));
      for (int c = 0; c < 2; ++c) {
        const Image& raw = c == 0 ? sf.left.image : sf.right.image;
        const ViewResult& w = c == 0 ? a.left : a.right;
        const ViewResult& v = c == 0 ? b.left : b.right;
        ASSERT_FALSE(v.augmented_box.empty());
        EXPECT_EQ(v.augmented.width(), v.augmented_box.x1 - v.augmented_box.x0);
        EXPECT_EQ(v.augmented.height(), v.augmented_box.y1 - v.augmented_box.y0);
        EXPECT_LT(v.augmented.width() * v.augmented.height(), raw.width() * raw.height() / 2);
        EXPECT_TRUE(pixels_equal(whole_augmented(raw, v), w.augmented));
        EXPECT_TRUE(pixels_equal(whole_augmented(raw, w), w.augmented));
        ViewResult made_whole = v;  // in place, as the live pipeline does for its window
        make_whole_augmented(raw, made_whole);
        EXPECT_TRUE(pixels_equal(made_whole.augmented, w.augmented));
        make_whole_augmented(raw, made_whole);  // already whole: unchanged
        EXPECT_TRUE(pixels_equal(made_whole.augmented, w.augmented));
        {  // the live pipeline's case: the box was made in a buffer that held a whole image (stale bytes)
          ViewResult reused = v;
          Image stale = Image::copy_of(w.augmented.cview());
          for (int y = 0; y < stale.height(); ++y)
            for (std::size_t k = 0; k < static_cast<std::size_t>(stale.width()) * bytes_per_pixel(fmt); ++k)
              stale.row(y)[k] = static_cast<std::uint8_t>(~stale.row(y)[k]);
          stale.reshape(v.augmented.width(), v.augmented.height(), fmt);
          std::memcpy(stale.data(), v.augmented.data(), v.augmented.stride_bytes() * v.augmented.height());
          reused.augmented = std::move(stale);
          make_whole_augmented(raw, reused);
          EXPECT_TRUE(pixels_equal(reused.augmented, w.augmented));
        }
        EXPECT_TRUE(pixels_equal(v.mask, w.mask));
        // Every change lies in the box.
        const int bpp = bytes_per_pixel(fmt);
        std::int64_t outside = 0;
        for (int y = 0; y < raw.height(); ++y)
          for (int x = 0; x < raw.width(); ++x) {
            const PixelBox& k = w.augmented_box;
            if (x >= k.x0 && x < k.x1 && y >= k.y0 && y < k.y1) continue;
            outside += std::memcmp(raw.row(y) + x * bpp, w.augmented.row(y) + x * bpp, bpp) != 0;
          }
        EXPECT_EQ(outside, 0);
      }
    }
  }
  // No box (nothing drawn): the whole image is the raw one.
  const Frame raw = test::gradient_frame(rig.left().model, PixelFormat::kRGB8, CameraId::kLeft);
  ViewResult nothing;
  EXPECT_TRUE(pixels_equal(whole_augmented(raw.image, nothing), raw.image));
}

TEST_P(RasterizerTest, BoomBehindTheReceiverIsNotDrawn) {
  const Rig rig = Rig::paper_default();
  auto aug = Augmenter::create(rig, options());
  ASSERT_TRUE(aug) << aug.error().message;
  Eigen::Vector3d receptacle;
  make_builtin_receiver(&receptacle);
  // Receiver moved 5 m from the contact point towards the left camera: the boom now pierces it
  // and its aft part is hidden behind the receiver.
  SceneState scene = contact_scene(rig, (*aug)->boom_model(), receptacle, {0.52, 0.0, 5.0});
  const Eigen::Vector3d tip = scene.T_body_receiver * receptacle;
  scene.T_body_receiver.translation_m += 5.0 * (rig.left().T_body_cam.translation_m - tip).normalized();
  ViewResult out;
  ASSERT_TRUE((*aug)->augment_view(
      0, test::gradient_frame(rig.left().model, PixelFormat::kRGB8, CameraId::kLeft), scene, out));
  // Where a ray hits both, the mask's boom bit must agree with which is nearer (ray caster).
  const RigCamera& cam = rig.left();
  const Pose T_cam_body = cam.T_body_cam.inverse();
  const Pose T_body_boom = boom_pose(rig.boom.pivot_body_m, scene.boom);
  test::RayCaster boom, receiver;
  boom.add((*aug)->boom_model().fixed, T_cam_body * T_body_boom);
  boom.add((*aug)->boom_model().telescope, T_cam_body * T_body_boom * telescope_pose(scene.boom));
  receiver.add((*aug)->receiver_model(), T_cam_body * scene.T_body_receiver);
  std::int64_t hidden = 0, wrong = 0;
  for (int y = 0; y < cam.model.height_px; y += 2)
    for (int x = 0; x < cam.model.width_px; x += 2) {
      const double xn = (x - cam.model.cx_px) / cam.model.fx_px, yn = (y - cam.model.cy_px) / cam.model.fy_px;
      const double zb = boom.hit_z(xn, yn), zr = receiver.hit_z(xn, yn);
      if (!std::isfinite(zb) || !std::isfinite(zr)) continue;
      const bool boom_in_front = zb < zr;
      hidden += !boom_in_front;
      const bool ours = out.mask.row(y)[x] & kMaskBoom;
      // Skip the 1-px band where the boom pierces the receiver.
      if (std::abs(zb - zr) > 0.05) wrong += ours != boom_in_front;
    }
  EXPECT_GT(hidden, 200) << "the scene should hide part of the boom behind the receiver";
  EXPECT_EQ(wrong, 0);
}

TEST_P(RasterizerTest, BoomEdgesAreAntiAliasedOnlyWhenAsked) {
  const Rig rig = Rig::paper_default();  // no distortion: the case where grids could coincide
  Eigen::Vector3d receptacle;
  make_builtin_receiver(&receptacle);
  for (bool aa : {true, false}) {
    AugmentOptions opt = options();
    opt.antialias = aa;
    auto aug = Augmenter::create(rig, opt);
    ASSERT_TRUE(aug) << aug.error().message;
    const SceneState scene = contact_scene(rig, (*aug)->boom_model(), receptacle, {0.5, 0.0, 2.0});
    const Frame raw = test::gradient_frame(rig.left().model, PixelFormat::kRGB8, CameraId::kLeft);
    ViewResult out;
    ASSERT_TRUE((*aug)->augment_view(0, raw, scene, out));
    // Partly covered edge pixels: centre outside the boom, yet blended with it.
    std::int64_t blended_outside = 0;
    for (int y = 0; y < raw.image.height(); ++y)
      for (int x = 0; x < raw.image.width(); ++x)
        if (!(out.mask.row(y)[x] & kMaskBoom) &&
            std::memcmp(raw.image.row(y) + 3 * x, out.augmented.row(y) + 3 * x, 3))
          ++blended_outside;
    if (aa)
      EXPECT_GT(blended_outside, 1000) << "no anti-aliased edge pixels";
    else
      EXPECT_EQ(blended_outside, 0) << "without anti-aliasing only boom pixels change";
  }
}

TEST_F(AugmenterTest, ReceiverOverlaysDrawTheModelButLeaveMasksAlone) {
  // The paper validates truth poses by drawing the receiver model over the real one.
  const Rig rig = Rig::paper_default();
  Eigen::Vector3d receptacle;
  make_builtin_receiver(&receptacle);
  ViewResult base;
  {
    auto aug = Augmenter::create(rig);
    ASSERT_TRUE(aug) << aug.error().message;
    const SceneState scene = contact_scene(rig, (*aug)->boom_model(), receptacle, {0.5, 0.0, 2.0});
    ASSERT_TRUE((*aug)->augment_view(
        0, test::gradient_frame(rig.left().model, PixelFormat::kRGB8, CameraId::kLeft), scene, base));
  }
  for (ReceiverDraw mode : {ReceiverDraw::kTranslucent, ReceiverDraw::kWireframe}) {
    AugmentOptions opt;
    opt.receiver_draw = mode;
    opt.rasterizer = Rasterizer::kCpu;  // overlays need the receiver's colour: always OpenGL
    auto aug = Augmenter::create(rig, opt);
    ASSERT_TRUE(aug) << aug.error().message;
    EXPECT_EQ((*aug)->rasterizer(), Rasterizer::kOpenGl);
    const SceneState scene = contact_scene(rig, (*aug)->boom_model(), receptacle, {0.5, 0.0, 2.0});
    const Frame raw = test::gradient_frame(rig.left().model, PixelFormat::kRGB8, CameraId::kLeft);
    ViewResult out;
    ASSERT_TRUE((*aug)->augment_view(0, raw, scene, out));
    EXPECT_TRUE(pixels_equal(out.mask, base.mask)) << "overlays must not change the masks";
    std::int64_t receiver_only = 0, changed = 0, changed_outside = 0;
    for (int y = 0; y < raw.image.height(); ++y)
      for (int x = 0; x < raw.image.width(); ++x) {
        const bool diff = std::memcmp(raw.image.row(y) + 3 * x, out.augmented.row(y) + 3 * x, 3) != 0;
        const std::uint8_t m = out.mask.row(y)[x];
        if (m == kMaskReceiver) receiver_only++, changed += diff;
        if (m == 0) changed_outside += diff;
      }
    ASSERT_GT(receiver_only, 10000);
    // Translucent tints every receiver pixel; a wireframe touches only its lines.
    if (mode == ReceiverDraw::kTranslucent) {
      EXPECT_GT(changed, receiver_only * 95 / 100);
    } else {
      EXPECT_GT(changed, receiver_only / 50);
      EXPECT_LT(changed, receiver_only * 9 / 10);
    }
    // Off the receiver only the boom's anti-aliased edge may differ.
    EXPECT_LT(changed_outside, 6000);
  }
}

// The two rasterisers side by side: the same masks but for a few silhouette pixels, and the same
// boom colours up to the shading model (GL lights each sample and blends four; the CPU path lights
// the vertices and interpolates to each pixel centre).
TEST_F(AugmenterTest, RasterizersAgreeWithEachOther) {
  const Rig rig = distorted_rig();
  Eigen::Vector3d receptacle;
  make_builtin_receiver(&receptacle);
  StereoResult out[2];
  for (int k = 0; k < 2; ++k) {
    AugmentOptions opt;
    opt.rasterizer = k == 0 ? Rasterizer::kOpenGl : Rasterizer::kCpu;
    auto aug = Augmenter::create(rig, opt);
    ASSERT_TRUE(aug) << aug.error().message;
    const SceneState scene = contact_scene(rig, (*aug)->boom_model(), receptacle, {0.5, 0.03, 2.5});
    StereoFrame sf;
    sf.left = test::gradient_frame(rig.left().model, PixelFormat::kRGB8, CameraId::kLeft);
    sf.right = test::gradient_frame(rig.right().model, PixelFormat::kRGB8, CameraId::kRight);
    ASSERT_TRUE((*aug)->augment(sf, scene, out[k]));
  }
  for (int c = 0; c < 2; ++c) {
    const ViewResult& gl = c == 0 ? out[0].left : out[0].right;
    const ViewResult& cpu = c == 0 ? out[1].left : out[1].right;
    std::int64_t mask_diff = 0, interior = 0, colour_far = 0, sum_diff = 0;
    int worst = 0;
    const int W = gl.mask.width(), H = gl.mask.height();
    for (int y = 1; y + 1 < H; ++y)
      for (int x = 1; x + 1 < W; ++x) {
        mask_diff += gl.mask.row(y)[x] != cpu.mask.row(y)[x];
        bool all_boom = true;  // boom pixel with boom all around: opaque in both
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) all_boom &= (gl.mask.row(y + dy)[x + dx] & kMaskBoom) != 0;
        if (!all_boom) continue;
        ++interior;
        int d = 0;
        for (int ch = 0; ch < 3; ++ch)
          d = std::max(d, std::abs(gl.augmented.row(y)[3 * x + ch] - cpu.augmented.row(y)[3 * x + ch]));
        worst = std::max(worst, d);
        sum_diff += d;
        // Apart across the texture's dark bands (GL blends samples of a mipmapped texture, the
        // CPU path samples it at the centre) and where per-vertex lighting departs from
        // per-sample lighting on the fairing's curved facets.
        colour_far += d > 8;
      }
    const double mean_diff =
        static_cast<double>(sum_diff) / static_cast<double>(std::max<std::int64_t>(interior, 1));
    std::printf(
        "camera %d: masks differ at %lld px; boom interior %lld px, colour mean diff %.2f, > 8 apart at "
        "%lld, "
        "max %d\n",
        c, static_cast<long long>(mask_diff), static_cast<long long>(interior), mean_diff,
        static_cast<long long>(colour_far), worst);
    EXPECT_GT(interior, 20000);
    EXPECT_LT(mask_diff, 40) << "both are exact at silhouettes up to a few pixels";
    EXPECT_LT(mean_diff, 2.0);
    EXPECT_LT(colour_far, interior / 20);
  }
}

// The camera look's finish (render/pbr.hpp): GL's vertex shader and the CPU rasteriser evaluate
// the same specular light at the vertices, so a glossy boom under a sun that its outer tube
// mirrors into the left camera agrees between them within the plain look's tolerances, and
// glints in both. The plain look ignores the finish: its pixels do not change with it.
TEST_F(AugmenterTest, RasterizersAgreeOnTheCameraLooksGlint) {
  Rig rig = distorted_rig();
  Eigen::Vector3d receptacle;
  make_builtin_receiver(&receptacle);
  const BoomModel boom = make_builtin_boom();
  SceneState scene = contact_scene(rig, boom, receptacle, {0.5, 0.03, 2.5});
  // The mirror direction of the left camera's view off the outer tube 4 m along, facing it.
  const Pose T_body_boom = boom_pose(rig.boom.pivot_body_m, scene.boom);
  const Eigen::Vector3d cam = rig.left().T_body_cam.translation_m,
                        p = T_body_boom * Eigen::Vector3d(4.0, 0, 0);
  const Eigen::Vector3d axis = T_body_boom.R().col(0), to_cam = cam - p;
  const Eigen::Vector3d n = (to_cam - to_cam.dot(axis) * axis).normalized(), v = to_cam.normalized();
  scene.light = SceneLight::sun(2 * n.dot(v) * n - v, true, LightSource::kConfigured);
  StereoFrame sf;
  sf.left = test::gradient_frame(rig.left().model, PixelFormat::kRGB8, CameraId::kLeft);
  sf.right = test::gradient_frame(rig.right().model, PixelFormat::kRGB8, CameraId::kRight);
  CameraLookParams lp;
  lp.psf_sigma_px = 0;  // no blur, no noise: the shading alone
  StereoResult out[2], plain[2][2];
  for (int k = 0; k < 2; ++k) {
    AugmentOptions opt;
    opt.rasterizer = k == 0 ? Rasterizer::kOpenGl : Rasterizer::kCpu;
    for (int gloss = 0; gloss < 2; ++gloss) {
      rig.boom.material = gloss ? SurfaceFinish{1.0, 0.1} : kPaintedBoom;
      auto aug = Augmenter::create(rig, opt);
      ASSERT_TRUE(aug) << aug.error().message;
      ASSERT_TRUE((*aug)->augment(sf, scene, plain[k][gloss]));
    }
    for (int c = 0; c < 2; ++c) {
      const Image& a = c ? plain[k][0].right.augmented : plain[k][0].left.augmented;
      const Image& b = c ? plain[k][1].right.augmented : plain[k][1].left.augmented;
      ASSERT_EQ(a.size_bytes(), b.size_bytes());
      EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size_bytes()), 0)
          << "the plain look changed with the finish";
    }
    rig.boom.material = SurfaceFinish{0.0, 0.3};
    opt.look = Look::kCamera;
    opt.camera_looks = {lp, lp};
    auto aug = Augmenter::create(rig, opt);
    ASSERT_TRUE(aug) << aug.error().message;
    ASSERT_TRUE((*aug)->augment(sf, scene, out[k]));
  }
  const ViewResult &gl = out[0].left, &cpu = out[1].left;
  std::int64_t interior = 0, colour_far = 0, sum_diff = 0, glint[2] = {0, 0};
  const int W = gl.mask.width(), H = gl.mask.height();
  for (int y = 1; y + 1 < H; ++y)
    for (int x = 1; x + 1 < W; ++x) {
      bool all_boom = true;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
          all_boom &= (gl.mask.row(y + dy)[x + dx] & cpu.mask.row(y + dy)[x + dx] & kMaskBoom) != 0;
      if (!all_boom) continue;
      ++interior;
      int d = 0;
      for (int ch = 0; ch < 3; ++ch)
        d = std::max(d, std::abs(gl.augmented.row(y)[3 * x + ch] - cpu.augmented.row(y)[3 * x + ch]));
      sum_diff += d;
      colour_far += d > 8;
      glint[0] += gl.augmented.row(y)[3 * x] == 255, glint[1] += cpu.augmented.row(y)[3 * x] == 255;
    }
  const double mean_diff =
      static_cast<double>(sum_diff) / static_cast<double>(std::max<std::int64_t>(interior, 1));
  std::printf(
      "camera look, glossy boom: interior %lld px, colour mean diff %.2f, > 8 apart at %lld; glint "
      "(saturated) GL %lld px, CPU %lld px\n",
      static_cast<long long>(interior), mean_diff, static_cast<long long>(colour_far),
      static_cast<long long>(glint[0]), static_cast<long long>(glint[1]));
  EXPECT_GT(interior, 20000);
  EXPECT_LT(mean_diff, 2.0);
  EXPECT_LT(colour_far, interior / 20);
  EXPECT_GT(glint[1], 200);
  EXPECT_NEAR(static_cast<double>(glint[0]), static_cast<double>(glint[1]),
              0.2 * static_cast<double>(glint[1]));
}

// A grid of n x n quads (two triangles each) over the parallelogram origin + s a + t b,
// s, t in [0, 1], appended to `m`. Both windings are drawn (custom models are not culled).
void add_grid(Mesh& m, const Eigen::Vector3d& origin, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
              int n) {
  const auto base = static_cast<std::uint32_t>(m.positions_m.size());
  const Eigen::Vector3d normal = a.cross(b).normalized();
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      m.positions_m.push_back((origin + a * (static_cast<double>(i) / n) + b * (static_cast<double>(j) / n))
                                  .cast<float>());
      m.normals.push_back(normal.cast<float>());
    }
  auto at = [&](int i, int j) { return base + static_cast<std::uint32_t>(j * (n + 1) + i); };
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i)
      m.indices.insert(m.indices.end(),
                       {at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j), at(i + 1, j + 1), at(i, j + 1)});
}

// A box centred at `c`, edges along R's columns times the half sizes `h`, each face an n x n grid.
Mesh box(const Eigen::Vector3d& c, const Eigen::Matrix3d& R, const Eigen::Vector3d& h, int n) {
  Mesh m;
  m.name = "box";
  for (int axis = 0; axis < 3; ++axis)
    for (double side : {-1.0, 1.0}) {
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      const Eigen::Vector3d face_c = c + side * h[axis] * R.col(axis);
      const Eigen::Vector3d a = 2 * h[u] * R.col(u), b = 2 * h[v] * R.col(v);
      add_grid(m, face_c - a / 2 - b / 2, a, b, n);
    }
  return m;
}

// How the left view's receiver bit and depth compare with the ray caster's nearest hit, counted
// only where that hit lies inside the camera's [near_m, far_m].
struct ReceiverVsOracle {
  std::int64_t oracle_px = 0, ours_px = 0, disagree = 0, far_from_edge = 0, off_clip_plane = 0;
  std::int64_t depth_bad = 0, beyond_far = 0, before_near = 0;
  double worst_depth = 0;
};
ReceiverVsOracle compare_receiver(const RigCamera& cam, const ViewResult& out, const test::RayCaster& receiver,
                                  double clip_tolerance_m) {
  const std::vector<Eigen::Vector2d> rays = test::opencv_pixel_rays(cam.model);
  const int W = cam.model.width_px, H = cam.model.height_px;
  std::vector<double> z(static_cast<std::size_t>(W) * H);
  std::vector<std::uint8_t> want(z.size());
  for (std::size_t i = 0; i < z.size(); ++i) {
    z[i] = receiver.hit_z(rays[i].x(), rays[i].y());
    want[i] = z[i] >= cam.near_m && z[i] <= cam.far_m;
  }
  ReceiverVsOracle r;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * W + x;
      const bool ours = (out.mask.row(y)[x] & kMaskReceiver) != 0;
      r.oracle_px += want[i], r.ours_px += ours;
      r.beyond_far += std::isfinite(z[i]) && z[i] > cam.far_m;
      r.before_near += z[i] < cam.near_m;
      if (ours && want[i]) {
        const double dz = std::abs(out.receiver_depth.z_m[i] - z[i]);
        r.worst_depth = std::max(r.worst_depth, dz);
        if (dz > 1e-4 && r.depth_bad++ < 5)
          std::printf("  depth at (%d, %d): %.6f m, ray caster %.6f m\n", x, y, out.receiver_depth.z_m[i], z[i]);
      }
      if (ours == static_cast<bool>(want[i])) continue;
      ++r.disagree;
      bool edge = false;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
          edge |= want[static_cast<std::size_t>(std::clamp(y + dy, 0, H - 1)) * W + std::clamp(x + dx, 0, W - 1)] !=
                  want[i];
      r.far_from_edge += !edge;
      // Where the clipping decides, it decides exactly: the hit is (almost) on a clipping plane.
      const bool on_plane = std::abs(z[i] - cam.near_m) < clip_tolerance_m ||
                            std::abs(z[i] - cam.far_m) < clip_tolerance_m;
      if (!on_plane && r.off_clip_plane++ < 5)
        std::printf("  (%d, %d): ours %d, ray caster hit at z %.6f m\n", x, y, ours, z[i]);
    }
  std::printf(
      "receiver: ray caster %lld px (%lld beyond far, %lld before near), ours %lld px, disagree %lld (%lld "
      "far from an edge, %lld off the clipping planes), depth worst %.3g m, %lld off by > 1e-4 m\n",
      static_cast<long long>(r.oracle_px), static_cast<long long>(r.beyond_far),
      static_cast<long long>(r.before_near), static_cast<long long>(r.ours_px), static_cast<long long>(r.disagree),
      static_cast<long long>(r.far_from_edge), static_cast<long long>(r.off_clip_plane), r.worst_depth,
      static_cast<long long>(r.depth_bad));
  return r;
}

// near_m and far_m are clipping planes in camera z, as GL's: a receiver wholly beyond far_m
// leaves no pixel, with either rasteriser.
TEST_P(RasterizerTest, NothingBeyondTheFarPlaneIsDrawn) {
  Rig rig = Rig::paper_default();
  for (RigCamera& c : rig.cameras) c.far_m = 25;
  AugmentOptions opt = options();
  auto aug = Augmenter::create(rig, opt);
  ASSERT_TRUE(aug) << aug.error().message;
  Eigen::Vector3d receptacle;
  make_builtin_receiver(&receptacle);
  SceneState scene = contact_scene(rig, (*aug)->boom_model(), receptacle, {0.52, 0.03, 3.0});
  // The receiver 45 m along the left camera's axis, level: its nearest point is beyond 25 m.
  scene.T_body_receiver.translation_m = rig.left().T_body_cam * Eigen::Vector3d(0, 0, 45);
  {
    test::RayCaster receiver;
    receiver.add((*aug)->receiver_model(), rig.left().T_body_cam.inverse() * scene.T_body_receiver);
    EXPECT_TRUE(std::isfinite(receiver.hit_z(0, 0))) << "the receiver must be in view";
    EXPECT_GT(receiver.hit_z(0, 0), 30);
  }
  StereoFrame sf;
  sf.left = test::gradient_frame(rig.left().model, PixelFormat::kRGB8, CameraId::kLeft);
  sf.right = test::gradient_frame(rig.right().model, PixelFormat::kRGB8, CameraId::kRight);
  StereoResult out;
  ASSERT_TRUE((*aug)->augment(sf, scene, out));
  for (const ViewResult* v : {&out.left, &out.right}) {
    std::int64_t receiver_px = 0, boom_px = 0;
    for (int y = 0; y < v->mask.height(); ++y)
      for (int x = 0; x < v->mask.width(); ++x) {
        receiver_px += (v->mask.row(y)[x] & kMaskReceiver) != 0;
        boom_px += (v->mask.row(y)[x] & kMaskBoom) != 0;
      }
    EXPECT_EQ(receiver_px, 0);
    EXPECT_GT(boom_px, 10000) << "the boom is nearer than far_m and must still be drawn";
  }
  EXPECT_EQ(out.stats.receiver_px_left, 0);
  EXPECT_EQ(out.stats.receiver_px_right, 0);
}

// A plate tilted away from the camera that crosses both clipping planes: receiver pixels exactly
// where the ray caster's hit is inside [near_m, far_m] (the only disagreements: rays hitting the
// plate within a hair of a plane), depth exact, with either rasteriser and lens.
TEST_P(RasterizerTest, ReceiverIsClippedExactlyAtTheNearAndFarPlanes) {
  for (bool distorted : {false, true}) {
    SCOPED_TRACE(distorted ? "radtan" : "pinhole");
    Rig rig = distorted ? distorted_rig() : Rig::paper_default();
    for (RigCamera& c : rig.cameras) c.near_m = 2, c.far_m = 6;
    const RigCamera& cam = rig.left();
    // Plane z = 3 + 1.8 Y + 0.3 X (left camera frame): the near plane crosses the upper image,
    // the far plane the lower; the plate's own borders lie outside [near_m, far_m] or the view.
    auto receiver = std::make_shared<Model>();
    Mesh plate;
    plate.name = "plate";
    const Eigen::Vector3d o(-14, -1.2, 3 + 1.8 * -1.2 + 0.3 * -14);
    add_grid(plate, o, Eigen::Vector3d(28, 0, 0.3 * 28), Eigen::Vector3d(0, 13.2, 1.8 * 13.2), 24);
    receiver->meshes.push_back(plate);
    AugmentOptions opt = options();
    opt.receiver_model = receiver;
    opt.stereo_classes = false;
    auto aug = Augmenter::create(rig, opt);
    ASSERT_TRUE(aug) << aug.error().message;
    SceneState scene;
    scene.boom = {0.35, 0.26, 0};            // out of the way
    scene.T_body_receiver = cam.T_body_cam;  // plate coordinates are left-camera coordinates
    ViewResult out;
    ASSERT_TRUE((*aug)->augment_view(0, test::gradient_frame(cam.model, PixelFormat::kRGB8, CameraId::kLeft),
                                     scene, out));
    test::RayCaster oracle;
    oracle.add(*receiver, Pose());
    const ReceiverVsOracle r = compare_receiver(cam, out, oracle, 1e-3);
    EXPECT_GT(r.oracle_px, 200000);
    EXPECT_GT(r.beyond_far, 100000) << "the plate must cross the far plane";
    EXPECT_GT(r.before_near, 50000) << "the plate must cross the near plane";
    EXPECT_EQ(r.off_clip_plane, 0);
    EXPECT_EQ(r.depth_bad, 0);
  }
}

// Two boxes through each other (a fin through a fuselage): where their faces cross, the 2x2
// samples around a pixel hold triangles of both, whose planes cross within the pixel. The depth
// must be the nearest surface's at the pixel centre, as the ray caster's, on every receiver pixel.
TEST_P(RasterizerTest, InterpenetratingPartsGiveTheNearestDepth) {
  for (bool distorted : {false, true}) {
    SCOPED_TRACE(distorted ? "radtan" : "pinhole");
    const Rig rig = distorted ? distorted_rig() : Rig::paper_default();
    const RigCamera& cam = rig.left();
    auto receiver = std::make_shared<Model>();
    receiver->meshes.push_back(box({0.3, 0.2, 20}, Eigen::Matrix3d::Identity(), {3, 1.5, 4}, 20));
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()) *
                               Eigen::AngleAxisd(0.6, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()))
                                  .toRotationMatrix();
    receiver->meshes.push_back(box({0.8, -0.4, 19}, R, {1.0, 3.5, 2.5}, 20));
    receiver->meshes.push_back(box({-1.5, 0.9, 18.5}, R.transpose(), {2.5, 0.3, 3.0}, 20));
    AugmentOptions opt = options();
    opt.receiver_model = receiver;
    opt.stereo_classes = false;
    auto aug = Augmenter::create(rig, opt);
    ASSERT_TRUE(aug) << aug.error().message;
    SceneState scene;
    scene.boom = {0.35, 0.26, 0};  // out of the way
    scene.T_body_receiver = cam.T_body_cam;
    ViewResult out;
    ASSERT_TRUE((*aug)->augment_view(0, test::gradient_frame(cam.model, PixelFormat::kRGB8, CameraId::kLeft),
                                     scene, out));
    test::RayCaster oracle;
    oracle.add(*receiver, Pose());
    const ReceiverVsOracle r = compare_receiver(cam, out, oracle, 0);
    EXPECT_GT(r.oracle_px, 50000);
    EXPECT_LE(r.disagree, r.oracle_px / 10000);
    EXPECT_EQ(r.far_from_edge, 0);
    EXPECT_EQ(r.depth_bad, 0);
  }
}

// A raw frame with sensor noise sigma^2 = a I + b over test::gradient_frame's signal, plus
// (textured) a checkerboard of +-30 DN, as a researcher's noisy input.
Frame noisy_frame(const CameraModel& cm, PixelFormat fmt, CameraId id, const NoiseLevelFunction& f, bool textured,
                  unsigned seed) {
  Frame fr = test::gradient_frame(cm, fmt, id);
  std::mt19937 rng(seed);
  std::normal_distribution<double> n01;
  const int bpp = bytes_per_pixel(fmt), nc = fmt == PixelFormat::kRGB8 || fmt == PixelFormat::kRGBA8 ? 3 : 1;
  for (int y = 0; y < fr.image.height(); ++y)
    for (int x = 0; x < fr.image.width(); ++x)
      for (int c = 0; c < nc; ++c) {
        std::uint8_t& px = fr.image.row(y)[x * bpp + c];
        const double s = std::clamp(0.6 * px + 40 + (textured ? ((x / 11 + y / 13) % 2 ? 30 : -30) : 0), 10.0, 240.0);
        const double v = s + std::sqrt(f.variance(noise_channel(fmt, x, y, c), s)) * n01(rng);
        px = static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
      }
  return fr;
}

// The ratio of the robust high-pass noise inside the boom (pixels whose 5x5 neighbourhood is
// all boom) to what the NLF gives at each pixel's level (read off the noise-free look), per
// channel; same-colour neighbours ([1 -2 1] x [1 -2 1], step 2 on a mosaic).
double boom_noise_ratio(const Image& look, const Image& level, const Image& mask, const NoiseLevelFunction& f, int c) {
  const int bpp = bytes_per_pixel(look.format()), s = is_bayer(look.format()) ? 2 : 1;
  std::vector<double> r;
  for (int y = 2 * s + 2; y < look.height() - 2 * s - 2; ++y)
    for (int x = 2 * s + 2; x < look.width() - 2 * s - 2; ++x) {
      bool inside = true;
      for (int dy = -2 * s; dy <= 2 * s && inside; ++dy)
        for (int dx = -2 * s; dx <= 2 * s && inside; ++dx) inside = (mask.row(y + dy)[x + dx] & kMaskBoom) != 0;
      if (!inside) continue;
      auto hp = [&](const Image& im) {
        auto p = [&](int dx, int dy) { return static_cast<double>(im.row(y + dy * s)[(x + dx * s) * bpp + c]); };
        return (p(-1, -1) - 2 * p(0, -1) + p(1, -1) - 2 * p(-1, 0) + 4 * p(0, 0) - 2 * p(1, 0) + p(-1, 1) -
                2 * p(0, 1) + p(1, 1)) / 6.0;
      };
      const double sigma = std::sqrt(f.variance(noise_channel(look.format(), x, y, c), level.row(y)[x * bpp + c]) + 1.0 / 12);
      r.push_back(std::abs(hp(look) - hp(level)) / sigma);  // the boom's own shading and texture cancel
    }
  if (r.size() < 2000) return 0;
  std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
  return r[r.size() / 2] / 0.6745;
}

// The camera look changes the boom's pixels only: masks, depth, statistics and classes are the
// plain look's; inside the boom the noise is the camera's (flat and textured, RGB and Bayer);
// nothing changes beyond the PSF's reach; the changed-box output is the whole image's box.
TEST_P(RasterizerTest, CameraLookAddsTheCamerasNoiseAndLeavesMasksAlone) {
  const Rig rig = distorted_rig();
  NoiseLevelFunction f;
  f.channels = 3;
  f.a = {0.15, 0.1, 0.2};
  f.b = {2.0, 1.0, 3.0};
  AugmentOptions plain_opt = options();
  AugmentOptions look_opt = plain_opt;
  look_opt.look = Look::kCamera;
  CameraLookParams lp;
  lp.noise = f;
  lp.psf_sigma_px = 0.8;
  look_opt.camera_looks = {lp, lp};
  // The noise-free camera look: the level each noisy pixel scatters about.
  AugmentOptions level_opt = look_opt;
  level_opt.camera_looks[0].noise = level_opt.camera_looks[1].noise = {};
  auto plain = Augmenter::create(rig, plain_opt);
  auto look = test::whole_and_box_augmenters(rig, look_opt);
  auto level = Augmenter::create(rig, level_opt);
  ASSERT_TRUE(plain && look && level);
  Eigen::Vector3d receptacle;
  make_builtin_receiver(&receptacle);
  SceneState scene = contact_scene(rig, (*plain)->boom_model(), receptacle, {0.5, 0.05, 2.0});
  scene.light = SceneLight::default_sun();
  for (const auto& [fmt, textured] : {std::pair{PixelFormat::kRGB8, false}, std::pair{PixelFormat::kBayerRG8, true},
                                      std::pair{PixelFormat::kMono8, true}}) {
    NoiseLevelFunction fm = f;
    if (fmt == PixelFormat::kMono8) fm.channels = 1;
    for (Augmenter* a : {look->whole.get(), look->box.get(), level->get()}) {
      CameraLookParams p = a->camera_look(0);
      if (!p.noise.empty()) p.noise = fm;
      ASSERT_TRUE(a->set_camera_look(0, p) && a->set_camera_look(1, p));
    }
    SCOPED_TRACE(std::string(to_string(fmt)) + (textured ? " textured" : " flat"));
    StereoFrame sf;
    sf.left = noisy_frame(rig.left().model, fmt, CameraId::kLeft, fm, textured, 1);
    sf.right = noisy_frame(rig.right().model, fmt, CameraId::kRight, fm, textured, 2);
    StereoResult p, w, b, l;
    ASSERT_TRUE((*plain)->augment(sf, scene, p));
    ASSERT_TRUE(look->whole->augment(sf, scene, w));
    ASSERT_TRUE(look->box->augment(sf, scene, b));
    ASSERT_TRUE((*level)->augment(sf, scene, l));
    EXPECT_EQ(p.stats, w.stats);
    EXPECT_EQ(p.stereo_classes, w.stereo_classes);
    for (int c = 0; c < 2; ++c) {
      const Image& raw = c == 0 ? sf.left.image : sf.right.image;
      const ViewResult &vp = c == 0 ? p.left : p.right, &vw = c == 0 ? w.left : w.right,
                       &vb = c == 0 ? b.left : b.right, &vl = c == 0 ? l.left : l.right;
      EXPECT_TRUE(pixels_equal(vp.mask, vw.mask));
      EXPECT_EQ(vp.receiver_depth.z_m, vw.receiver_depth.z_m);
      EXPECT_TRUE(vp.boom_alpha.empty());
      EXPECT_TRUE(pixels_equal(whole_augmented(raw, vb), vw.augmented));
      EXPECT_FALSE(pixels_equal(vp.augmented, vw.augmented));
      const int nc = fmt == PixelFormat::kRGB8 ? 3 : 1;
      for (int ch = 0; ch < nc; ++ch) {
        const double ratio = boom_noise_ratio(vw.augmented, vl.augmented, vw.mask, fm, ch);
        EXPECT_GT(ratio, 0.9) << "camera " << c << " channel " << ch;
        EXPECT_LT(ratio, 1.1) << "camera " << c << " channel " << ch;
      }
      // Beyond the PSF's reach of the boom's coverage and its shadow, the raw pixels stay.
      const int m = psf_margin_px(lp), bpp = bytes_per_pixel(fmt);
      std::int64_t far_changed = 0;
      for (int y = 0; y < raw.height(); ++y)
        for (int x = 0; x < raw.width(); ++x) {
          if (!std::memcmp(raw.row(y) + x * bpp, vw.augmented.row(y) + x * bpp, bpp)) continue;
          bool near = false;
          for (int dy = -m; dy <= m && !near; ++dy)
            for (int dx = -m; dx <= m && !near; ++dx) {
              const int yy = std::clamp(y + dy, 0, raw.height() - 1), xx = std::clamp(x + dx, 0, raw.width() - 1);
              near = vw.boom_alpha.row(yy)[xx] != 0 || (vw.mask.row(yy)[xx] & kMaskShadow);
            }
          far_changed += !near;
        }
      EXPECT_EQ(far_changed, 0);
    }
  }
}

// The camera look's light: a sun behind the boom leaves its lit side away from the cameras (darker
// than a sun behind the cameras), a sun below the horizon leaves the sky's ambient only.
TEST_P(RasterizerTest, CameraLookShadesTheBoomWithTheScenesLight) {
  const Rig rig = Rig::paper_default();
  AugmentOptions opt = options();
  opt.look = Look::kCamera;
  CameraLookParams lp;
  lp.psf_sigma_px = 0;
  opt.camera_looks = {lp, lp};
  auto aug = Augmenter::create(rig, opt);
  ASSERT_TRUE(aug) << aug.error().message;
  Eigen::Vector3d receptacle;
  make_builtin_receiver(&receptacle);
  SceneState scene = contact_scene(rig, (*aug)->boom_model(), receptacle, {0.5, 0.0, 2.0});
  const Frame raw = test::gradient_frame(rig.left().model, PixelFormat::kMono8, CameraId::kLeft);
  auto mean_boom = [&](const SceneLight& light) {
    scene.light = light;
    ViewResult out;
    EXPECT_TRUE((*aug)->augment_view(0, raw, scene, out));
    double sum = 0;
    std::int64_t n = 0;
    for (int y = 0; y < raw.image.height(); ++y)
      for (int x = 0; x < raw.image.width(); ++x)
        if (out.mask.row(y)[x] & kMaskBoom) sum += out.augmented.row(y)[x], ++n;
    EXPECT_GT(n, 1000);
    return sum / std::max<std::int64_t>(n, 1);
  };
  // The cameras sit forward of the pivot and below the boom's line (extended forward, it passes
  // 1.9 m above them): they see the boom's underside, lit by light from below and ahead, not by a
  // sun overhead (then the ambient alone, as at night).
  const double lit = mean_boom(SceneLight::sun(Eigen::Vector3d(0.2, 0.1, 1), true, LightSource::kConfigured));
  const double overhead = mean_boom(SceneLight::sun(Eigen::Vector3d(0.2, 0.1, -1), true, LightSource::kConfigured));
  const double night = mean_boom(SceneLight::sun(Eigen::Vector3d(0.2, 0.1, -1), false, LightSource::kConfigured));
  EXPECT_GT(lit, 2 * overhead);
  EXPECT_NEAR(overhead, night, 0.3 * night);
}

// The boom's triangles in a camera's frame, and whether the ray p + t s (t > 0) meets one: brute
// force (Moeller-Trumbore, each triangle behind a bounding-sphere test), nothing shared with
// render/boom_shadow.
struct BoomTriangles {
  std::vector<std::array<Eigen::Vector3d, 3>> tris;
  std::vector<std::pair<Eigen::Vector3d, double>> spheres;
  void add(const Model& model, const Pose& T_cam_obj) {
    for (const Mesh& m : model.meshes)
      for (std::size_t k = 0; k + 2 < m.indices.size(); k += 3) {
        std::array<Eigen::Vector3d, 3> t;
        for (int j = 0; j < 3; ++j) t[j] = T_cam_obj * m.positions_m[m.indices[k + j]].cast<double>();
        const Eigen::Vector3d c = (t[0] + t[1] + t[2]) / 3;
        spheres.emplace_back(c, std::max({(t[0] - c).norm(), (t[1] - c).norm(), (t[2] - c).norm()}) + 1e-6);
        tris.push_back(t);
      }
  }
  bool hit(const Eigen::Vector3d& p, const Eigen::Vector3d& s) const {
    for (std::size_t i = 0; i < tris.size(); ++i) {
      const Eigen::Vector3d w = spheres[i].first - p;
      const double along = w.dot(s);
      if (along < -spheres[i].second || (w - along * s).squaredNorm() > spheres[i].second * spheres[i].second)
        continue;
      const auto& t = tris[i];
      const Eigen::Vector3d e1 = t[1] - t[0], e2 = t[2] - t[0], h = s.cross(e2);
      const double a = e1.dot(h);
      if (std::abs(a) < 1e-15) continue;
      const Eigen::Vector3d q = p - t[0];
      const double u = q.dot(h) / a;
      if (u < 0 || u > 1) continue;
      const Eigen::Vector3d r = q.cross(e1);
      const double v = s.dot(r) / a;
      if (v < 0 || u + v > 1) continue;
      if (e2.dot(r) / a > 1e-9) return true;
    }
    return false;
  }
};

// A sun overhead and a little ahead: the boom's shadow falls on the receiver at contact.
SceneLight overhead_sun() {
  return SceneLight::sun(Eigen::Vector3d(0.25, -0.1, -1), true, LightSource::kConfigured);
}

// kMaskShadow against a ray cast towards the sun from the receiver's surface point (OpenCV's
// pixel rays, the ray caster's depth, brute force over the boom); the same bits in either look
// and in the statistics; none with the sun down.
TEST_P(MaskOracleTest, ShadowBitAgreesWithARayCastTowardsTheSun) {
  const auto [distorted, raster] = GetParam();
  const Rig rig = distorted ? distorted_rig() : Rig::paper_default();
  AugmentOptions opt;
  opt.rasterizer = raster;
  AugmentOptions look_opt = opt;
  look_opt.look = Look::kCamera;
  auto aug = Augmenter::create(rig, opt);
  auto look = Augmenter::create(rig, look_opt);
  ASSERT_TRUE(aug && look);
  Eigen::Vector3d receptacle;
  make_builtin_receiver(&receptacle);
  const BoomArticulation a{0.52, 0.03, 3.0};
  SceneState scene = contact_scene(rig, (*aug)->boom_model(), receptacle, a);
  scene.light = overhead_sun();
  StereoFrame sf;
  sf.left = test::gradient_frame(rig.left().model, PixelFormat::kRGB8, CameraId::kLeft);
  sf.right = test::gradient_frame(rig.right().model, PixelFormat::kRGB8, CameraId::kRight);
  StereoResult out, looked;
  ASSERT_TRUE((*aug)->augment(sf, scene, out));
  ASSERT_TRUE((*look)->augment(sf, scene, looked));
  EXPECT_EQ(out.stats, looked.stats);
  for (int c = 0; c < 2; ++c) {
    const RigCamera& cam = rig.cameras[c];
    const Image& ours = c == 0 ? out.left.mask : out.right.mask;
    EXPECT_TRUE(pixels_equal(ours, c == 0 ? looked.left.mask : looked.right.mask));
    const Pose T_cam_body = cam.T_body_cam.inverse();
    const Pose T_body_boom = boom_pose(rig.boom.pivot_body_m, a);
    test::RayCaster boom, receiver;
    BoomTriangles occluder;
    boom.add((*aug)->boom_model().fixed, T_cam_body * T_body_boom);
    boom.add((*aug)->boom_model().telescope, T_cam_body * T_body_boom * telescope_pose(a));
    occluder.add((*aug)->boom_model().fixed, T_cam_body * T_body_boom);
    occluder.add((*aug)->boom_model().telescope, T_cam_body * T_body_boom * telescope_pose(a));
    receiver.add((*aug)->receiver_model(), T_cam_body * scene.T_body_receiver);
    const std::vector<Eigen::Vector2d> rays = test::opencv_pixel_rays(cam.model);
    const Image oracle = test::ray_cast_mask(cam.model, rays, boom, receiver);
    const Eigen::Vector3d sun = (T_cam_body.R() * scene.light.towards_light_body).normalized();
    const int W = ours.width(), H = ours.height();
    // The oracle's bit at a pixel: receiver alone there, and the sun's ray from its point blocked.
    auto shadowed = [&](int x, int y) {
      if (oracle.row(y)[x] != kMaskReceiver) return false;
      const Eigen::Vector2d& r = rays[static_cast<std::size_t>(y) * W + x];
      return occluder.hit(receiver.hit_z(r.x(), r.y()) * Eigen::Vector3d(r.x(), r.y(), 1), sun);
    };
    std::int64_t compared = 0, in_shadow = 0, disagree = 0, far_from_edge = 0, bits = 0;
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        const std::uint8_t m = ours.row(y)[x];
        bits += (m & kMaskShadow) != 0;
        if ((m & kMaskShadow) && (m & kMaskBoom)) {
          ADD_FAILURE() << "shadow under the boom at " << x << ", " << y;
        }
        if (x % 2 || y % 2 || (m & 3) != oracle.row(y)[x] || oracle.row(y)[x] != kMaskReceiver) continue;
        const bool expected = shadowed(x, y);
        ++compared, in_shadow += expected;
        if (expected == ((m & kMaskShadow) != 0)) continue;
        ++disagree;
        bool edge = false;  // the oracle changes within one pixel
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx)
            edge |= shadowed(std::clamp(x + dx, 0, W - 1), std::clamp(y + dy, 0, H - 1)) != expected;
        far_from_edge += !edge;
      }
    const OcclusionStats& st = out.stats;
    EXPECT_EQ(bits, c == 0 ? st.shadow_px_left : st.shadow_px_right);
    std::printf("camera %d: %lld receiver px compared, %lld in shadow, %lld disagree (%lld far from an edge)\n", c,
                static_cast<long long>(compared), static_cast<long long>(in_shadow), static_cast<long long>(disagree),
                static_cast<long long>(far_from_edge));
    EXPECT_GT(in_shadow, 300) << "the scene must show the boom's shadow on the receiver";
    EXPECT_LE(disagree, std::max<std::int64_t>(in_shadow / 200, 3));
    EXPECT_EQ(far_from_edge, 0);
  }
  // The sun below the horizon, or unknown: no shadow.
  for (const SceneLight& l : {SceneLight::sun(scene.light.towards_light_body, false, LightSource::kEphemeris),
                              SceneLight::fixed()}) {
    scene.light = l;
    ASSERT_TRUE((*aug)->augment(sf, scene, out));
    EXPECT_EQ(out.stats.shadow_px_left + out.stats.shadow_px_right, 0);
  }
}

// The camera look darkens the receiver in the boom's shadow by the direct light's share there (a
// flat, noise-free frame: the ratio is read off directly), tops its noise up to the camera's
// level at the darker value (a noisy frame), and the changed-box output holds it all.
TEST_P(RasterizerTest, CameraLookDarkensTheReceiverInTheBoomsShadow) {
  const Rig rig = Rig::paper_default();
  AugmentOptions opt = options();
  opt.look = Look::kCamera;
  CameraLookParams lp;
  lp.psf_sigma_px = 0;
  opt.camera_looks = {lp, lp};
  auto look = test::whole_and_box_augmenters(rig, opt);
  ASSERT_TRUE(look);
  Eigen::Vector3d receptacle;
  make_builtin_receiver(&receptacle);
  SceneState scene = contact_scene(rig, look->whole->boom_model(), receptacle, {0.52, 0.03, 3.0});
  scene.light = overhead_sun();
  // A flat grey frame: in the shadow the value is 128 (1 - share) with share = direct (n.s) / all.
  StereoFrame sf;
  for (int c = 0; c < 2; ++c) {
    Frame& f = c == 0 ? sf.left : sf.right;
    f = test::gradient_frame(rig.cameras[c].model, PixelFormat::kMono8, c == 0 ? CameraId::kLeft : CameraId::kRight);
    for (int y = 0; y < f.image.height(); ++y) std::memset(f.image.row(y), 128, f.image.width());
  }
  StereoResult w, b;
  ASSERT_TRUE(look->whole->augment(sf, scene, w));
  ASSERT_TRUE(look->box->augment(sf, scene, b));
  std::int64_t shadow = 0, darker = 0;
  double lo = 255, hi = 0;
  for (int c = 0; c < 2; ++c) {
    const ViewResult &vw = c == 0 ? w.left : w.right, &vb = c == 0 ? b.left : b.right;
    const Image& raw = c == 0 ? sf.left.image : sf.right.image;
    EXPECT_TRUE(pixels_equal(whole_augmented(raw, vb), vw.augmented));
    for (int y = 0; y < raw.height(); ++y)
      for (int x = 0; x < raw.width(); ++x) {
        const std::uint8_t m = vw.mask.row(y)[x], v = vw.augmented.row(y)[x];
        if (!(m & kMaskShadow)) {
          if (!vw.boom_alpha.row(y)[x]) {
            EXPECT_EQ(v, 128) << x << ", " << y;
          }
          continue;
        }
        if (vw.boom_alpha.row(y)[x]) continue;  // the boom's anti-aliased edge over it
        ++shadow, darker += v < 128;
        lo = std::min(lo, static_cast<double>(v)), hi = std::max(hi, static_cast<double>(v));
      }
  }
  // SceneLight::sun()'s clear sky: direct 0.8, sky and ground 0.2: a surface facing the sun keeps
  // 0.2 / 1.0 of its light; one at a grazing angle nearly all.
  EXPECT_GT(shadow, 600);
  EXPECT_GT(darker, shadow * 9 / 10);
  EXPECT_GE(lo, 128 * 0.2 - 1);
  EXPECT_LT(lo, 128 * 0.5);
  std::printf("shadow %lld px, %lld darker, values %.0f..%.0f\n", static_cast<long long>(shadow),
              static_cast<long long>(darker), lo, hi);

  // Noisy frames: the shadow's noise is the camera's at its darker level (its interior, 5x5 all
  // shadow, no boom), against the noise-free look's values there.
  NoiseLevelFunction f;
  f.channels = 1;
  f.a = {0.2, 0, 0};
  f.b = {2.0, 0, 0};
  auto level = Augmenter::create(rig, opt);
  ASSERT_TRUE(level);
  lp.noise = f;
  ASSERT_TRUE(look->whole->set_camera_look(0, lp) && look->whole->set_camera_look(1, lp));
  sf.left = noisy_frame(rig.left().model, PixelFormat::kMono8, CameraId::kLeft, f, false, 3);
  sf.right = noisy_frame(rig.right().model, PixelFormat::kMono8, CameraId::kRight, f, false, 4);
  StereoResult l;
  ASSERT_TRUE(look->whole->augment(sf, scene, w));
  ASSERT_TRUE((*level)->augment(sf, scene, l));
  for (int c = 0; c < 2; ++c) {
    const ViewResult &vw = c == 0 ? w.left : w.right, &vl = c == 0 ? l.left : l.right;
    std::vector<double> r;
    for (int y = 3; y < vw.mask.height() - 3; ++y)
      for (int x = 3; x < vw.mask.width() - 3; ++x) {
        bool inside = true;
        for (int dy = -2; dy <= 2 && inside; ++dy)
          for (int dx = -2; dx <= 2 && inside; ++dx)
            inside = (vw.mask.row(y + dy)[x + dx] & kMaskShadow) && !vw.boom_alpha.row(y + dy)[x + dx];
        if (!inside || vl.augmented.row(y)[x] >= 120) continue;  // darkened (faces the sun)
        auto p = [&](int dx, int dy) { return static_cast<double>(vw.augmented.row(y + dy)[x + dx]); };
        const double hp = (p(-1, -1) - 2 * p(0, -1) + p(1, -1) - 2 * p(-1, 0) + 4 * p(0, 0) - 2 * p(1, 0) +
                           p(-1, 1) - 2 * p(0, 1) + p(1, 1)) / 6.0;
        r.push_back(std::abs(hp) / std::sqrt(f.variance(0, vl.augmented.row(y)[x]) + 1.0 / 12));
      }
    ASSERT_GT(r.size(), 300u) << "camera " << c;
    std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
    const double ratio = r[r.size() / 2] / 0.6745;
    std::printf("camera %d: noise in the shadow over the camera's: %.3f (%zu px)\n", c, ratio, r.size());
    EXPECT_GT(ratio, 0.9);
    EXPECT_LT(ratio, 1.1);
  }
}

// ---- Motion blur over the exposure (render/motion_blur.hpp) --------------------------------------

// A rig whose cameras look square at a plate boom: both pinhole, 6 m beside the boom (which lies
// level along body -x at elevation 0), looking along body +y, image x along body -x (the
// telescope's motion), image y down.
constexpr double kPlateDepthM = 6.0;
Rig plate_rig() {
  Rig rig = Rig::paper_default();
  Eigen::Matrix3d R;
  R.col(0) = Eigen::Vector3d(-1, 0, 0), R.col(1) = Eigen::Vector3d(0, 0, 1),
  R.col(2) = Eigen::Vector3d(0, 1, 0);
  const Eigen::Vector3d at = rig.boom.pivot_body_m + Eigen::Vector3d(-3.5, -kPlateDepthM, 0);
  rig.cameras[0].T_body_cam = Pose::from(R, at);
  rig.cameras[1].T_body_cam = Pose::from(R, at + Eigen::Vector3d(-0.5, 0, 0));
  return rig;
}

// The boom as two plates facing the cameras: the telescope's 2 m square (centred 3 m out on the
// telescope, 3.5 m from the pivot at extension 0.5 m: the image's centre), turned 5 deg in its
// plane so that its edges cross the pixel grid at every phase; the fixed part's smaller one above
// it. Both white.
constexpr double kPlateTurnRad = 5 * kPi / 180;
std::shared_ptr<const BoomModel> plate_boom() {
  auto b = std::make_shared<BoomModel>();
  Mesh tele, fixed;
  const Eigen::Vector3d a = 2.0 * Eigen::Vector3d(std::cos(kPlateTurnRad), 0, std::sin(kPlateTurnRad)),
                        up = 2.0 * Eigen::Vector3d(-std::sin(kPlateTurnRad), 0, std::cos(kPlateTurnRad));
  add_grid(tele, Eigen::Vector3d(3.0, 0, 0) - 0.5 * (a + up), a, up, 8);
  add_grid(fixed, {1.0, 0, -2.2}, {1.0, 0, 0}, {0, 0, 0.6}, 4);
  for (Mesh* m : {&tele, &fixed}) m->base_color = {1.0f, 1.0f, 1.0f};
  b->telescope.meshes.push_back(tele);
  b->fixed.meshes.push_back(fixed);
  return b;
}

// The telescope plate's centre in camera `c`'s image at articulation `a`.
Eigen::Vector2d plate_centre_px(const Rig& rig, int c, const BoomArticulation& a) {
  const Pose T =
      rig.cameras[c].T_body_cam.inverse() * boom_pose(rig.boom.pivot_body_m, a) * telescope_pose(a);
  return *rig.cameras[c].model.project(T * Eigen::Vector3d(3.0, 0, 0));
}

// The 10-90 % width of a rising edge sampled at whole steps, `level(k)` its normalised values
// from outside (0) in: the crossings interpolated linearly between samples. NaN if it never rises.
template <typename Level>
double rise_width(Level level, int count) {
  double prev = 0, x10 = NAN;
  for (int k = 0; k < count; ++k) {
    const double n = level(k);
    if (std::isnan(x10) && n >= 0.1) x10 = k - 1 + (0.1 - prev) / (n - prev);
    if (n >= 0.9) return k - 1 + (0.9 - prev) / (n - prev) - x10;
    prev = n;
  }
  return NAN;
}

// The width rise_width() measures on an edge blurred by the pixel's area (1 px box), a box of
// `motion_px` (the trail) and a Gaussian PSF (Phi averaged over the two boxes by midpoint
// quadrature), averaged over the edge's sub-pixel phases as a slanted edge's rows sample them.
double analytic_edge_width_px(double motion_px, double sigma_px) {
  auto level = [&](double x) {
    constexpr int n = 60;
    double sum = 0;
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        const double u = (i + 0.5) / n - 0.5, w = ((j + 0.5) / n - 0.5) * motion_px;
        sum += 0.5 * std::erfc(-(x - u - w) / (sigma_px * std::sqrt(2.0)));
      }
    return sum / (n * n);
  };
  constexpr int kPhases = 32;
  double sum = 0;
  for (int p = 0; p < kPhases; ++p) {
    const double x0 = -10 + (p + 0.5) / kPhases;
    sum += rise_width([&](int k) { return level(x0 + k); }, 20);
  }
  return sum / kPhases;
}

// The telescope plate's edges in a view over a flat background `bg`, its centre at `centre`: the
// 10-90 % widths of its left and right edges (profiles along rows: across the motion) and of its
// top and bottom edges (profiles along columns), averaged over the plate's middle half.
struct PlateEdges {
  double left_px = 0, right_px = 0, top_px = 0, bottom_px = 0;
};
PlateEdges plate_edges(const Image& img, int bg, const Eigen::Vector2d& centre) {
  const int cx = static_cast<int>(std::lround(centre.x())), cy = static_cast<int>(std::lround(centre.y()));
  auto at = [&](int x, int y) { return static_cast<double>(img.row(y)[3 * x + 1]); };  // green
  const double top = at(cx, cy);
  auto width = [&](int x, int y, int dx, int dy) {
    return rise_width([&](int k) { return (at(x + k * dx, y + k * dy) - bg) / (top - bg); }, 200);
  };
  PlateEdges e;
  int n = 0;
  for (int t = -100; t <= 100; t += 2, ++n) {
    e.left_px += width(cx - 300, cy + t, 1, 0), e.right_px += width(cx + 300, cy + t, -1, 0);
    e.top_px += width(cx + t, cy - 300, 0, 1), e.bottom_px += width(cx + t, cy + 300, 0, -1);
  }
  e.left_px /= n, e.right_px /= n, e.top_px /= n, e.bottom_px /= n;
  return e;
}

StereoFrame flat_pair(const Rig& rig, int level, std::int64_t exposure_ns = 0) {
  StereoFrame sf;
  for (int c = 0; c < 2; ++c) {
    Frame& f = c == 0 ? sf.left : sf.right;
    f.image = Image(rig.cameras[c].model.width_px, rig.cameras[c].model.height_px, PixelFormat::kRGB8);
    for (int y = 0; y < f.image.height(); ++y) std::memset(f.image.row(y), level, 3 * f.image.width());
    f.camera = c == 0 ? CameraId::kLeft : CameraId::kRight;
    f.t_ns = 1'000'000'000;
    f.exposure_ns = exposure_ns;
  }
  sf.t_key_ns = sf.left.t_ns;
  return sf;
}

// The telescope moving 3.9 px across the cameras over a 10 ms exposure: its edges across the motion
// widen as a 3.9 px box convolved with the pixel and the PSF says; its edges along the motion and
// the still plate's stay; masks, depth and statistics are mid-exposure's, the plain look's.
TEST_P(RasterizerTest, MotionBlurWidensTheEdgesAcrossTheMotionByTheTrail) {
  const Rig rig = plate_rig();
  constexpr double kTrailPx = 3.9, kExposureMs = 10.0, kSigmaPx = 0.7;
  const double fx = rig.left().model.fx_px;
  SceneState scene;
  scene.boom = {0.0, 0.0, 0.5};
  scene.receiver_present = false;
  scene.boom_rate_per_s.extension_m = kTrailPx * kPlateDepthM / fx / (1e-3 * kExposureMs);
  AugmentOptions opt = options();
  opt.boom_model = plate_boom();
  opt.look = Look::kCamera;
  CameraLookParams lp;
  lp.psf_sigma_px = kSigmaPx;
  lp.exposure_ms = kExposureMs;
  opt.camera_looks = {lp, lp};
  AugmentOptions plain_opt = opt;
  plain_opt.look = Look::kPlain;
  auto aug = Augmenter::create(rig, opt);
  auto plain = Augmenter::create(rig, plain_opt);
  ASSERT_TRUE(aug && plain);
  const StereoFrame sf = flat_pair(rig, 40);
  StereoResult moving, still, flat;
  ASSERT_TRUE((*aug)->augment(sf, scene, moving));
  EXPECT_EQ((*aug)->timings().motion_samples, 8);  // 3.9 px at 0.5 px
  ASSERT_TRUE((*plain)->augment(sf, scene, flat));
  SceneState held = scene;
  held.boom_rate_per_s = {};
  ASSERT_TRUE((*aug)->augment(sf, held, still));
  EXPECT_EQ((*aug)->timings().motion_samples, 1);

  EXPECT_EQ(moving.stats, flat.stats);
  const double w_still = analytic_edge_width_px(0, kSigmaPx),
               w_moving = analytic_edge_width_px(kTrailPx, kSigmaPx);
  for (int c = 0; c < 2; ++c) {
    const ViewResult &m = c ? moving.right : moving.left, &s = c ? still.right : still.left,
                     &p = c ? flat.right : flat.left;
    EXPECT_TRUE(pixels_equal(m.mask, p.mask)) << "camera " << c;
    EXPECT_TRUE(pixels_equal(m.mask, s.mask)) << "camera " << c;
    EXPECT_EQ(m.receiver_depth.z_m, p.receiver_depth.z_m);
    EXPECT_TRUE(pixels_equal(m.boom_alpha, s.boom_alpha)) << "the coverage reported is mid-exposure's";
    const Eigen::Vector2d centre = plate_centre_px(rig, c, scene.boom);
    const PlateEdges em = plate_edges(m.augmented, 40, centre), es = plate_edges(s.augmented, 40, centre);
    std::printf(
        "%s camera %d: still L %.3f R %.3f T %.3f B %.3f px; moving L %.3f R %.3f T %.3f B %.3f px; "
        "analytic %.3f / %.3f px\n",
        to_string(GetParam()), c, es.left_px, es.right_px, es.top_px, es.bottom_px, em.left_px, em.right_px,
        em.top_px, em.bottom_px, w_still, w_moving);
    // Measured 0.11 px wider than the analytic edge still and moving alike (the anti-aliased
    // coverage is not exactly the pixel's box); the widening within 0.03 px of the analytic.
    for (double w : {es.left_px, es.right_px, es.top_px, es.bottom_px}) EXPECT_NEAR(w, w_still, 0.2);
    EXPECT_NEAR(em.left_px, w_moving, 0.2);
    EXPECT_NEAR(em.right_px, w_moving, 0.2);
    EXPECT_NEAR(em.left_px - es.left_px, w_moving - w_still, 0.1);
    EXPECT_NEAR(em.right_px - es.right_px, w_moving - w_still, 0.1);
    // The plate's 5 deg turn puts sin 5 deg of the trail (0.34 px) across its top and bottom.
    EXPECT_NEAR(em.top_px, es.top_px, 0.1) << "an edge along the motion is not blurred by it";
    EXPECT_NEAR(em.bottom_px, es.bottom_px, 0.1);
  }
}

// A boom held still, an exposure of 0 or one not known draw the same bytes as before motion blur
// (one instant, the mid-exposure's); the frames' own exposure stands in for the rig's; after a
// blurred frame the augmenter's next still frame is a fresh augmenter's.
TEST_P(RasterizerTest, MotionBlurLeavesAStillBoomOrAnInstantExposureAsItWas) {
  const Rig rig = plate_rig();
  SceneState moving;
  moving.boom = {0.0, 0.0, 0.5};
  moving.receiver_present = false;
  moving.boom_rate_per_s = {0.2, 0.1, 2.0};
  SceneState still = moving;
  still.boom_rate_per_s = {};
  auto make = [&](double exposure_ms) {
    AugmentOptions opt = options();
    opt.boom_model = plate_boom();
    opt.look = Look::kCamera;
    CameraLookParams lp;
    lp.exposure_ms = exposure_ms;
    NoiseLevelFunction f;
    f.channels = 1, f.a.fill(0.1), f.b.fill(1.0);
    lp.noise = f;
    opt.camera_looks = {lp, lp};
    auto a = Augmenter::create(rig, opt);
    EXPECT_TRUE(a) << a.error().message;
    return std::move(*a);
  };
  auto unknown = make(-1), instant = make(0), known = make(10);
  const StereoFrame sf = flat_pair(rig, 40), sf_exposed = flat_pair(rig, 40, 10'000'000);
  StereoResult ref, r;
  ASSERT_TRUE(unknown->augment(sf, moving, ref));  // no exposure known: drawn still
  ASSERT_TRUE(instant->augment(sf_exposed, moving, r));
  EXPECT_TRUE(pixels_equal(ref.left.augmented, r.left.augmented)) << "an instant's exposure";
  ASSERT_TRUE(known->augment(sf, still, r));
  EXPECT_TRUE(pixels_equal(ref.left.augmented, r.left.augmented)) << "a still boom";
  EXPECT_TRUE(pixels_equal(ref.right.augmented, r.right.augmented));
  StereoResult blurred, from_frames;
  ASSERT_TRUE(known->augment(sf, moving, blurred));
  EXPECT_GT(known->timings().motion_samples, 1);
  EXPECT_FALSE(pixels_equal(ref.left.augmented, blurred.left.augmented));
  ASSERT_TRUE(unknown->augment(sf_exposed, moving, from_frames));
  EXPECT_TRUE(pixels_equal(blurred.left.augmented, from_frames.left.augmented)) << "the frames' exposure";
  ASSERT_TRUE(known->augment(sf, still, r));  // after a blurred frame
  EXPECT_TRUE(pixels_equal(ref.left.augmented, r.left.augmented));
  EXPECT_TRUE(pixels_equal(ref.left.mask, r.left.mask));
  EXPECT_TRUE(pixels_equal(ref.right.augmented, r.right.augmented));
}

// GL and the CPU rasteriser blur the same trail: their moving plates agree as their still ones do.
TEST_F(AugmenterTest, RasterizersAgreeOnMotionBlur) {
  const Rig rig = plate_rig();
  SceneState scene;
  scene.boom = {0.0, 0.0, 0.5};
  scene.receiver_present = false;
  scene.boom_rate_per_s = {0.05, 0.02, 1.5};
  StereoResult out[2];
  for (int k = 0; k < 2; ++k) {
    AugmentOptions opt;
    opt.rasterizer = k == 0 ? Rasterizer::kOpenGl : Rasterizer::kCpu;
    opt.boom_model = plate_boom();
    opt.look = Look::kCamera;
    CameraLookParams lp;
    lp.exposure_ms = 10;
    opt.camera_looks = {lp, lp};
    auto aug = Augmenter::create(rig, opt);
    ASSERT_TRUE(aug) << aug.error().message;
    ASSERT_TRUE((*aug)->augment(flat_pair(rig, 40), scene, out[k]));
    EXPECT_GT((*aug)->timings().motion_samples, 4);
  }
  for (int c = 0; c < 2; ++c) {
    const Image &gl = (c ? out[0].right : out[0].left).augmented,
                &cpu = (c ? out[1].right : out[1].left).augmented;
    std::int64_t n = 0, sum = 0, far = 0;
    for (int y = 0; y < gl.height(); ++y)
      for (int x = 0; x < 3 * gl.width(); ++x) {
        const int d = std::abs(gl.row(y)[x] - cpu.row(y)[x]);
        if (gl.row(y)[x] == 40 && cpu.row(y)[x] == 40) continue;
        ++n, sum += d, far += d > 8;
      }
    const double mean = static_cast<double>(sum) / static_cast<double>(std::max<std::int64_t>(n, 1));
    std::printf("camera %d: motion-blurred plates, %lld values, mean diff %.2f, > 8 apart %lld\n", c,
                static_cast<long long>(n), mean, static_cast<long long>(far));
    EXPECT_GT(n, 100000);
    EXPECT_LT(mean, 2.0);
    EXPECT_LT(far, n / 50);
    const Eigen::Vector2d centre = plate_centre_px(rig, c, scene.boom);
    const PlateEdges a = plate_edges(gl, 40, centre), b = plate_edges(cpu, 40, centre);
    EXPECT_NEAR(a.left_px, b.left_px, 0.15);
    EXPECT_NEAR(a.right_px, b.right_px, 0.15);
    EXPECT_NEAR(a.top_px, b.top_px, 0.15);
  }
}

// kAuto takes the CPU rasteriser exactly where OpenGL is itself software.
TEST_F(AugmenterTest, AutoPicksTheCpuRasterizerOnSoftwareGl) {
  auto aug = Augmenter::create(Rig::paper_default());
  ASSERT_TRUE(aug) << aug.error().message;
  const std::string renderer = context()->renderer();
  const bool software =
      renderer.find("llvmpipe") != std::string::npos || renderer.find("softpipe") != std::string::npos;
  EXPECT_EQ((*aug)->rasterizer(), software ? Rasterizer::kCpu : Rasterizer::kOpenGl) << renderer;
}

}  // namespace
}  // namespace augrig
