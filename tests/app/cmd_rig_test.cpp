// augrig rig show RIG [--strict] through the real binary: the paper's rig printed with both
// cameras, its baseline and the receptacle's pixel at contact (checked against the rig's numbers
// and a pinhole projection of the nozzle tip computed here from the boom's geometry); a rig given in
// millimetres warned about (exit 0, or 1 with --strict); a capture-only rig; missing and
// malformed rig files named with their line; usage errors.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "core/conventions.hpp"
#include "render/models.hpp"
#include "render/rig.hpp"
#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

namespace fs = std::filesystem;

int augrig(const std::string& args, std::string* output) {
  return test::run_augrig(args, output);
}

bool has(const std::string& s, const std::string& what) {
  return s.find(what) != std::string::npos;
}

std::string write_rig(const std::string& dir, const std::string& name, const Rig& rig) {
  const std::string path = dir + "/" + name;
  std::ofstream(path) << rig_to_yaml(rig);
  return path;
}

// The number after `key` in `s` (NaN when absent).
double number_after(const std::string& s, const std::string& key, std::size_t from = 0) {
  const std::size_t at = s.find(key, from);
  if (at == std::string::npos) return std::nan("");
  return std::stod(s.substr(at + key.size()));
}

TEST(CmdRig, PaperRigShowsBothCamerasTheBaselineAndNoWarnings) {
  std::string out;
  ASSERT_EQ(augrig("rig show default", &out), 0) << out;
  const Rig rig = Rig::paper_default();
  EXPECT_TRUE(has(out, "rig <built-in>: 2 camera(s)")) << out;
  EXPECT_TRUE(has(out, "camera 'left': 1280x960, none")) << out;
  EXPECT_TRUE(has(out, "camera 'right': 1280x960, none")) << out;
  // The baseline: the distance between the cameras' centres in the rig (0.5 m in the paper).
  const double baseline = (rig.left().T_body_cam.translation_m - rig.right().T_body_cam.translation_m).norm();
  EXPECT_NEAR(baseline, 0.5, 1e-12);
  EXPECT_TRUE(has(out, "baseline 0.5000 m")) << out;
  EXPECT_TRUE(has(out, "No warnings.")) << out;
  EXPECT_FALSE(has(out, "WARNING")) << out;
  // The intrinsics as the rig has them.
  EXPECT_NEAR(number_after(out, "fx "), rig.left().model.fx_px, 0.005) << out;
  EXPECT_NEAR(number_after(out, " cx "), rig.left().model.cx_px, 0.005) << out;
  // Field of view: 56 deg horizontal, as the paper's rig is defined.
  EXPECT_NEAR(number_after(out, "field of view "), 56.0, 0.005) << out;

  // The receptacle at contact: the nozzle tip with the boom at the middle of its limits, here
  // from the boom's geometry (pivot + length along the boom's direction) and a pinhole projection.
  const BoomLimits& L = rig.boom.limits;
  const double el = 0.5 * (L.elevation_min_rad + L.elevation_max_rad);
  const double az = 0.0;  // the limits straddle 0
  const double ext = 0.5 * (L.extension_min_m + L.extension_max_m);
  const double length = BoomDimensions{}.nozzle_tip_m(ext);
  // The boom points aft (-x), starboard (+y) with azimuth, down (+z) with elevation.
  const Eigen::Vector3d dir(-std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
  const Eigen::Vector3d tip = rig.boom.pivot_body_m + length * dir;
  for (int c = 0; c < 2; ++c) {
    const RigCamera& cam = rig.cameras[c];
    ASSERT_EQ(cam.model.distortion, DistortionModel::kNone);
    const Eigen::Vector3d p = cam.T_body_cam.inverse() * tip;
    ASSERT_GT(p.z(), 0);
    const double u = cam.model.fx_px * p.x() / p.z() + cam.model.cx_px;
    const double v = cam.model.fy_px * p.y() / p.z() + cam.model.cy_px;
    const std::size_t block = out.find("camera '" + cam.name + "'");
    ASSERT_NE(block, std::string::npos);
    const std::size_t at = out.find("receptacle at contact: ", block);
    ASSERT_NE(at, std::string::npos) << out;
    EXPECT_NEAR(number_after(out, "receptacle at contact: ", block), p.z(), 0.0005 + 1e-9) << cam.name;
    EXPECT_NEAR(number_after(out, "pixel (", at), u, 0.05 + 1e-9) << cam.name << "\n" << out;
    EXPECT_NEAR(number_after(out, ", ", out.find("pixel (", at)), v, 0.05 + 1e-9) << cam.name;
  }
  char where[128];
  std::snprintf(where, sizeof where, "the receptacle is at [%.3f, %.3f, %.3f] m", tip.x(), tip.y() + 0.0,
                tip.z());
  EXPECT_TRUE(has(out, where)) << where << "\n" << out;

  // Nothing to warn about: --strict changes nothing.
  std::string strict;
  EXPECT_EQ(augrig("rig show default --strict", &strict), 0) << strict;
  EXPECT_EQ(strict, out);
}

TEST(CmdRig, TranslationsInMillimetresAreWarnedAboutAndStrictFails) {
  const std::string dir = test::output_dir("cmd_rig_mm");
  Rig rig = Rig::paper_default();
  for (RigCamera& c : rig.cameras) c.T_body_cam.translation_m *= 1000.0;  // mm given as m
  const std::string path = write_rig(dir, "rig_mm.yaml", rig);
  std::string out;
  EXPECT_EQ(augrig("rig show " + path, &out), 0) << "warnings alone do not fail without --strict\n" << out;
  EXPECT_TRUE(has(out, "baseline 500.0000 m")) << out;
  EXPECT_TRUE(has(out, "WARNING: the cameras are 500.000 m apart")) << out;
  EXPECT_TRUE(has(out, "millimetres")) << out;
  EXPECT_FALSE(has(out, "No warnings.")) << out;
  std::string strict;
  EXPECT_EQ(augrig("rig show " + path + " --strict", &strict), 1) << strict;
  // The summary is printed all the same.
  EXPECT_TRUE(has(strict, "WARNING: the cameras are 500.000 m apart")) << strict;
  EXPECT_TRUE(has(strict, "camera 'left'")) << strict;
}

TEST(CmdRig, CaptureOnlyRigHasNoBoomAndNoContact) {
  const std::string dir = test::output_dir("cmd_rig_capture_only");
  Rig rig = Rig::paper_default();
  rig.boom.configured = false;
  const std::string path = write_rig(dir, "capture.yaml", rig);
  {
    std::ifstream in(path);
    const std::string yaml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    ASSERT_FALSE(has(yaml, "boom:")) << "a capture-only rig is one without a boom section\n" << yaml;
  }
  std::string out;
  ASSERT_EQ(augrig("rig show " + path + " --strict", &out), 0) << out;
  EXPECT_TRUE(has(out, "rig " + path + ": 2 camera(s)")) << out;
  EXPECT_TRUE(has(out, "boom: none: a capture-only rig")) << out;
  EXPECT_FALSE(has(out, "receptacle at contact")) << out;
  EXPECT_FALSE(has(out, "the receptacle is at")) << out;
  EXPECT_TRUE(has(out, "baseline 0.5000 m")) << out;
  EXPECT_TRUE(has(out, "No warnings.")) << out;
}

TEST(CmdRig, MissingOrMalformedRigFilesFailNamingFileAndLine) {
  const std::string dir = test::output_dir("cmd_rig_bad");
  std::string out;
  const std::string missing = dir + "/no_such_rig.yaml";
  EXPECT_EQ(augrig("rig show " + missing, &out), 1) << out;
  EXPECT_TRUE(has(out, missing)) << out;
  EXPECT_FALSE(has(out, "camera '")) << out;

  // bad_syntax.yaml: a flow list never closed (the parser notices on line 6).
  const std::string syntax = test::data_path("rigs/bad_syntax.yaml");
  EXPECT_EQ(augrig("rig show " + syntax, &out), 1) << out;
  EXPECT_TRUE(has(out, syntax + ":6:")) << out;

  // bad_typo.yaml: 'nera_m' on line 8.
  const std::string typo = test::data_path("rigs/bad_typo.yaml");
  EXPECT_EQ(augrig("rig show " + typo, &out), 1) << out;
  EXPECT_TRUE(has(out, typo + ":8")) << out;
  EXPECT_TRUE(has(out, "nera_m")) << out;

  // A value out of range: a camera 0 pixels wide, on line 4.
  const std::string bad = dir + "/bad_value.yaml";
  std::ofstream(bad) << "augrig_rig: 1\n"
                        "cameras:\n"
                        "  - name: left\n"
                        "    resolution: [0, 960]\n"
                        "    hfov_deg: 56\n"
                        "    T_body_cam: {translation_m: [0.0, 0.25, 2.0], mount_ypr_deg: [180, -25, 0]}\n"
                        "  - name: right\n"
                        "    resolution: [1280, 960]\n"
                        "    hfov_deg: 56\n"
                        "    T_body_cam: {translation_m: [0.0, -0.25, 2.0], mount_ypr_deg: [180, -25, 0]}\n";
  EXPECT_EQ(augrig("rig show " + bad, &out), 1) << out;
  EXPECT_TRUE(has(out, bad + ":4:")) << out;
  EXPECT_TRUE(has(out, "resolution")) << out;
}

TEST(CmdRig, UsageErrors) {
  std::string out;
  EXPECT_EQ(augrig("rig list default", &out), 2) << out;
  EXPECT_TRUE(has(out, "augrig rig show RIG")) << out;
  EXPECT_EQ(augrig("rig show", &out), 2) << out;
  EXPECT_EQ(augrig("rig show default --no-such-flag", &out), 2) << out;
  EXPECT_EQ(augrig("rig --help", &out), 0) << out;
  EXPECT_TRUE(has(out, "--strict")) << out;
}

}  // namespace
}  // namespace augrig
