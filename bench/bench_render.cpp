// bench_render: per-stage cost of augmenting one 1280x960 stereo frame on this machine
// (llvmpipe here), for the boom path alone and with the receiver proxy and stereo classes,
// with and without lens distortion, and how much of the image the boom and receiver cover (the
// cost is per covered pixel on a software rasteriser), with each rasteriser (OpenGL, and the CPU
// one of render/soft_raster.hpp) in the same run, and each form of the augmented output (the whole
// image, a frame-sized copy per camera; or the changed box, AugmentedOutput). Prints tables for
// docs/PERFORMANCE.md.
// With --look camera the boom also gets the camera look (render/camera_look.hpp: the default sun,
// a 0.7 px PSF, a configured noise level function) and the `look` column its share.
//   build/bench_render [--frames N] [--case K] [--raster opengl|cpu|both] [--augmented whole|box|both]
//                      [--look plain|camera|both]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <iterator>
#include <string>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "render/augmenter.hpp"
#include "render/gl_context.hpp"
#include "render/visualize.hpp"

using namespace augrig;

namespace {

struct Series {
  std::vector<double> v;
  double median() const {
    auto c = v;
    std::sort(c.begin(), c.end());
    return c.empty() ? 0 : c[c.size() / 2];
  }
  double p90() const {
    auto c = v;
    std::sort(c.begin(), c.end());
    return c.empty() ? 0 : c[std::min(c.size() - 1, c.size() * 9 / 10)];
  }
};

Frame textured_frame(const CameraModel& cm, PixelFormat fmt, CameraId id) {
  Frame f;
  f.image = Image(cm.width_px, cm.height_px, fmt);
  const int bpp = bytes_per_pixel(fmt);
  for (int y = 0; y < cm.height_px; ++y)
    for (int x = 0; x < cm.width_px * bpp; ++x)
      f.image.row(y)[x] = static_cast<std::uint8_t>((x * 13) ^ (y * 7));
  f.camera = id;
  return f;
}

// `cameras_forward_m` moves both cameras forward along the body x axis: the cost is per pixel the
// boom covers, and the default rig's cameras sit only 4 m from the pivot.
Rig rig_with(bool distorted, double cameras_forward_m = 0) {
  Rig rig = Rig::paper_default();
  for (RigCamera& c : rig.cameras) c.T_body_cam.translation_m.x() += cameras_forward_m;
  if (distorted)
    for (RigCamera& c : rig.cameras) {
      c.model.distortion = DistortionModel::kRadTan;
      c.model.coeffs = {-0.28, 0.12, 8e-4, -6e-4, -0.02};
    }
  return rig;
}

void run_case(const char* name, bool distorted, bool receiver, PixelFormat fmt, int frames, bool profile,
              double cameras_forward_m, Rasterizer raster, AugmentedOutput output, Look look) {
  const Rig rig = rig_with(distorted, cameras_forward_m);
  AugmentOptions opt;
  opt.look = look;
  CameraLookParams lp;
  lp.noise = {3, {0.2, 0.15, 0.25}, {2.0, 1.5, 2.5}};
  opt.camera_looks = {lp, lp};
  opt.rasterizer = raster;
  opt.augmented_output = output;
  opt.receiver_proxy = receiver;
  opt.stereo_classes = receiver;
  opt.profile_stages = profile;
  auto aug = Augmenter::create(rig, opt);
  if (!aug) {
    std::fprintf(stderr, "%s\n", aug.error().message.c_str());
    std::exit(1);
  }
  Eigen::Vector3d receptacle;
  make_builtin_receiver(&receptacle);
  StereoFrame sf;
  sf.left = textured_frame(rig.left().model, fmt, CameraId::kLeft);
  sf.right = textured_frame(rig.right().model, fmt, CameraId::kRight);
  StereoResult out;
  Series render, masks, look_ms, shadow_ms, shadow_pct, stats, total, debayer, clear, draw, readback, boom_pct, recv_pct;
  for (int i = -5; i < frames; ++i) {  // 5 warm-up frames
    // Sweep the approach from pre-contact to contact so boxes and coverage vary.
    const double s = std::max(0, i) / std::max(1.0, frames - 1.0);
    SceneState scene =
        scene_at_contact(rig, (*aug)->boom_model().dims, receptacle, {0.50 + 0.04 * s, 0.02, 1.0 + 3.0 * s},
                         Eigen::Vector3d(-12.0 * (1 - s), 0, 4.0 * (1 - s)));
    // A low sun ahead (19 deg up): the boom's shadow falls on the receiver over the approach.
    scene.light = receiver ? SceneLight::sun(Eigen::Vector3d(1, -0.1, -0.35), true, LightSource::kConfigured)
                           : SceneLight::default_sun();
    sf.left.t_ns = sf.right.t_ns = i;
    const auto t0 = std::chrono::steady_clock::now();
    if (auto st = (*aug)->augment(sf, scene, out); !st) {
      std::fprintf(stderr, "%s\n", st.error().message.c_str());
      std::exit(1);
    }
    const auto t1 = std::chrono::steady_clock::now();
    Image rgb_l, rgb_r;
    if (is_bayer(fmt)) {  // the whole augmented images, for display
      rgb_l = to_rgb8(whole_augmented(sf.left.image, out.left));
      rgb_r = to_rgb8(whole_augmented(sf.right.image, out.right));
    }
    const auto t2 = std::chrono::steady_clock::now();
    if (i < 0) continue;
    const auto& t = (*aug)->timings();
    render.v.push_back(t.render_ms);
    boom_pct.v.push_back(out.stats.boom_pct_left);
    recv_pct.v.push_back(out.stats.receiver_pct_left);
    clear.v.push_back(t.gl_clear_ms);
    draw.v.push_back(t.gl_draw_ms);
    readback.v.push_back(t.gl_readback_ms);
    masks.v.push_back(t.masks_ms);
    look_ms.v.push_back(t.look_ms);
    shadow_ms.v.push_back(t.shadow_ms);
    shadow_pct.v.push_back(out.stats.shadow_pct_left);
    stats.v.push_back(t.stats_ms);
    total.v.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    debayer.v.push_back(std::chrono::duration<double, std::milli>(t2 - t1).count());
  }
  if (profile) {
    std::printf("| %-44s | %6.2f | %6.2f | %6.2f |\n", name, clear.median(), draw.median(),
                readback.median());
    return;
  }
  std::printf(
      "| %-44s | %-6s | %-6s | %-6s | %5.1f%% | %5.1f%% | %5.1f%% | %6.2f | %6.2f | %6.2f | %6.2f | %6.2f | %6.2f | "
      "%7.2f / %-6.2f |\n",
      name, to_string((*aug)->rasterizer()), output == AugmentedOutput::kWholeImage ? "whole" : "box",
      to_string(look), boom_pct.median(), receiver ? recv_pct.median() : 0.0, receiver ? shadow_pct.median() : 0.0,
      render.median(), masks.median(), shadow_ms.median(), look_ms.median(), stats.median(), is_bayer(fmt) ? debayer.median() : 0.0, total.median(), total.p90());
}

}  // namespace

int main(int argc, char** argv) {
  int frames = 60, only = -1;
  std::vector<Rasterizer> rasters = {Rasterizer::kOpenGl, Rasterizer::kCpu};
  std::vector<AugmentedOutput> outputs = {AugmentedOutput::kWholeImage, AugmentedOutput::kChangedBox};
  std::vector<Look> looks = {Look::kPlain};
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--frames") == 0 && i + 1 < argc) {
      frames = std::atoi(argv[++i]);
    } else if (std::strcmp(argv[i], "--case") == 0 && i + 1 < argc) {
      only = std::atoi(argv[++i]);
    } else if (std::strcmp(argv[i], "--raster") == 0 && i + 1 < argc) {
      const std::string r = argv[++i];
      if (r == "opengl")
        rasters = {Rasterizer::kOpenGl};
      else if (r == "cpu")
        rasters = {Rasterizer::kCpu};
      else if (r != "both")
        return std::fprintf(stderr, "bench_render: --raster takes opengl, cpu or both, not '%s'\n",
                            r.c_str()),
               2;
    } else if (std::strcmp(argv[i], "--augmented") == 0 && i + 1 < argc) {
      const std::string o = argv[++i];
      if (o == "whole")
        outputs = {AugmentedOutput::kWholeImage};
      else if (o == "box")
        outputs = {AugmentedOutput::kChangedBox};
      else if (o != "both")
        return std::fprintf(stderr, "bench_render: --augmented takes whole, box or both, not '%s'\n",
                            o.c_str()),
               2;
    } else if (std::strcmp(argv[i], "--look") == 0 && i + 1 < argc) {
      const std::string l = argv[++i];
      Look one = Look::kPlain;
      if (l == "both")
        looks = {Look::kPlain, Look::kCamera};
      else if (parse_look(l, one))
        looks = {one};
      else
        return std::fprintf(stderr, "bench_render: --look takes plain, camera or both, not '%s'\n", l.c_str()), 2;
    } else {
      std::fprintf(stderr,
                   "usage: bench_render [--frames N] [--case 0..6] [--raster opengl|cpu|both] "
                   "[--augmented whole|box|both] [--look plain|camera|both]\n");
      return 2;
    }
  }
  auto ctx = create_gl_context(GlBackend::kEglHeadless);
  if (!ctx) {
    std::fprintf(stderr, "%s\n", ctx.error().message.c_str());
    return 1;
  }
  std::printf("bench_render: 1280x960 stereo, %d frames per case, medians in ms (total: median / p90)\n",
              frames);
  std::printf("renderer: %s\n\n", (*ctx)->renderer().c_str());
  std::printf(
      "| case                                         | raster | output | look   | boom | receiver | shadow (%% of "
      "receiver) | render | masks+composite | shadow | look | stats | debayer | total (median / p90) |\n");
  std::printf(
      "|----------------------------------------------|--------|--------|--------|-----:|-----:|-----:|-------:|"
      "-------:|-----:|-----:|------:|------:|------:|\n");
  struct Case {
    const char* name;
    bool distorted, receiver;
    PixelFormat fmt;
    double cameras_forward_m;
  };
  const Case cases[] = {
      {"boom path, pinhole, RGB8", false, false, PixelFormat::kRGB8, 0},
      {"boom path, radtan distortion, RGB8", true, false, PixelFormat::kRGB8, 0},
      {"boom path, radtan, BayerRG8", true, false, PixelFormat::kBayerRG8, 0},
      {"boom + receiver + stereo classes, pinhole", false, true, PixelFormat::kRGB8, 0},
      {"boom + receiver + stereo classes, radtan", true, true, PixelFormat::kRGB8, 0},
      {"boom path, radtan, cameras 10 m from pivot", true, false, PixelFormat::kRGB8, 6},
      {"boom + receiver + classes, radtan, 10 m", true, true, PixelFormat::kRGB8, 6},
  };
  constexpr int kCases = static_cast<int>(std::size(cases));
  for (int i = 0; i < kCases; ++i)
    for (const Rasterizer r : rasters)
      for (const AugmentedOutput o : outputs)
        for (const Look l : looks)
          if (only < 0 || only == i)
            run_case(cases[i].name, cases[i].distorted, cases[i].receiver, cases[i].fmt, frames, false,
                     cases[i].cameras_forward_m, r, o, l);
  if (std::find(rasters.begin(), rasters.end(), Rasterizer::kOpenGl) == rasters.end()) return 0;
  // Where the GL time goes (glFinish between stages, so these sum to more than `render` above).
  std::printf("\nGL stages, both views (ms, medians, with glFinish between stages):\n\n");
  std::printf("| case                                         | clear  | draw   | readback |\n");
  std::printf("|----------------------------------------------|-------:|-------:|-------:|\n");
  for (int i = 0; i < kCases; ++i)
    if (only < 0 || only == i)
      run_case(cases[i].name, cases[i].distorted, cases[i].receiver, cases[i].fmt, frames, true,
               cases[i].cameras_forward_m, Rasterizer::kOpenGl, outputs.back(), looks.back());
  return 0;
}
