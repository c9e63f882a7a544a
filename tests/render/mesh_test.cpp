// Mesh basics and the glTF / OBJ loaders: counts, axis conversion, node transforms, materials,
// textures and uv orientation, and a clear Error (never a crash) for every broken file.
// Test models: tests/data/models (written by make_test_models.py there).
#include "render/mesh.hpp"

#include <filesystem>
#include <fstream>
#include <string>
#include <tuple>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

using Eigen::Vector3f;

ModelSource source(const std::string& name, ModelAxes axes = ModelAxes::gltf(), double scale = 1.0) {
  return ModelSource{test::data_path("models/" + name), axes, scale};
}

// RGBA of the texel under (u, v) (nearest, v down from the top row).
std::array<int, 4> texel(const Texture& t, float u, float v) {
  const int c = std::clamp(static_cast<int>(u * t.width), 0, t.width - 1);
  const int r = std::clamp(static_cast<int>(v * t.height), 0, t.height - 1);
  const std::uint8_t* p = t.rgba.data() + (static_cast<std::size_t>(r) * t.width + c) * 4;
  return {p[0], p[1], p[2], p[3]};
}

void expect_near(const Vector3f& a, const Vector3f& b, float tol = 1e-5f) {
  EXPECT_TRUE((a - b).cwiseAbs().maxCoeff() <= tol)
      << "got " << a.transpose() << ", expected " << b.transpose();
}

// Signed volume of a closed mesh (positive when the faces point outward).
double signed_volume(const Mesh& m) {
  double v = 0;
  for (std::size_t t = 0; t < m.indices.size(); t += 3) {
    const Eigen::Vector3d a = m.positions_m[m.indices[t]].cast<double>();
    const Eigen::Vector3d b = m.positions_m[m.indices[t + 1]].cast<double>();
    const Eigen::Vector3d c = m.positions_m[m.indices[t + 2]].cast<double>();
    v += a.dot(b.cross(c)) / 6.0;
  }
  return v;
}

TEST(Mesh, BoundsAndCounts) {
  Mesh m;
  EXPECT_EQ(m.triangle_count(), 0u);
  EXPECT_EQ(m.bounds().first, Vector3f::Zero());
  m.positions_m = {{1, 2, 3}, {-1, 5, 0}, {0, 0, 7}};
  m.indices = {0, 1, 2};
  EXPECT_EQ(m.triangle_count(), 1u);
  expect_near(m.bounds().first, {-1, 0, 0});
  expect_near(m.bounds().second, {1, 5, 7});
  Model model;
  model.meshes = {m, Mesh{}, m};  // empty meshes do not drag the bounds to the origin
  model.meshes[2].positions_m[0] = {10, 2, 3};
  EXPECT_EQ(model.triangle_count(), 2u);
  expect_near(model.bounds().first, {-1, 0, 0});
  expect_near(model.bounds().second, {10, 5, 7});
}

TEST(Mesh, ComputeNormalsAreaWeightedAndUnit) {
  // Two triangles sharing vertex 0: a big one in the x-y plane (normal +z), a small one in the
  // x-z plane (normal -y). The shared normal leans towards the bigger face.
  Mesh m;
  m.positions_m = {{0, 0, 0}, {4, 0, 0}, {0, 4, 0}, {1, 0, 0}, {0, 0, 1}};
  m.indices = {0, 1, 2, 0, 3, 4};
  compute_normals(m);
  ASSERT_EQ(m.normals.size(), 5u);
  for (const auto& n : m.normals) EXPECT_NEAR(n.norm(), 1.0f, 1e-6f);
  expect_near(m.normals[1], {0, 0, 1});
  expect_near(m.normals[3], {0, -1, 0});
  const Vector3f expected = Vector3f(0, -0.5f, 8.0f).normalized();  // weights 2*area: 16 vs 1
  expect_near(m.normals[0], expected);
}

TEST(LoadGltf, EmbeddedBoxNodeTransformsAndGltfAxes) {
  auto model = load_model(source("box.gltf"));
  ASSERT_TRUE(model) << model.error().message;
  // Only the default scene: the copy 100 m away in scene 1 is not loaded.
  ASSERT_EQ(model->meshes.size(), 1u);
  const Mesh& m = model->meshes[0];
  EXPECT_EQ(m.positions_m.size(), 24u);
  EXPECT_EQ(m.triangle_count(), 12u);
  // File box x [0,1] y [0,0.5] z [-0.5,0.5]; parent matrix +1 z, child +1 z and 180 deg about z:
  // x [-1,0] y [-0.5,0] z [1.5,2.5]. glTF axes: FRD x = +z, y = -x, z = -y.
  const auto [lo, hi] = model->bounds();
  expect_near(lo, {1.5f, 0.0f, 0.0f});
  expect_near(hi, {2.5f, 1.0f, 0.5f});
  EXPECT_GT(signed_volume(m), 0.0);
  EXPECT_NEAR(signed_volume(m), 0.5, 1e-5);
  // NORMAL absent: computed, unit, outward (the face at FRD x = 2.5 points along +x).
  ASSERT_EQ(m.normals.size(), 24u);
  for (std::size_t i = 0; i < 24; ++i) {
    EXPECT_NEAR(m.normals[i].norm(), 1.0f, 1e-5f);
    if (m.positions_m[i].x() > 2.49f && m.normals[i].x() > 0.5f) expect_near(m.normals[i], {1, 0, 0});
  }
  // Material and texture; glTF uv (0,0) is the top-left texel (red), (1,1) the bottom-right (white).
  expect_near(m.base_color, {0.2f, 0.4f, 0.6f});
  ASSERT_TRUE(m.texture);
  EXPECT_EQ(m.texture->width, 4);
  EXPECT_EQ(m.texture->height, 4);
  ASSERT_EQ(m.uvs.size(), 24u);
  EXPECT_EQ(texel(*m.texture, 0.1f, 0.1f), (std::array<int, 4>{255, 0, 0, 255}));
  EXPECT_EQ(texel(*m.texture, 0.9f, 0.1f), (std::array<int, 4>{0, 255, 0, 255}));
  EXPECT_EQ(texel(*m.texture, 0.1f, 0.9f), (std::array<int, 4>{0, 0, 255, 255}));
  EXPECT_EQ(texel(*m.texture, 0.9f, 0.9f), (std::array<int, 4>{255, 255, 255, 255}));
  // uvs are passed through unflipped.
  bool seen_00 = false, seen_11 = false;
  for (const auto& uv : m.uvs) {
    seen_00 = seen_00 || uv.isApprox(Eigen::Vector2f(0, 0));
    seen_11 = seen_11 || uv.isApprox(Eigen::Vector2f(1, 1));
  }
  EXPECT_TRUE(seen_00 && seen_11);
}

TEST(LoadGltf, ForwardUnitCubeEndsUpAlongFrdX) {
  // The same file with FRD axes (no conversion) keeps the box along file +z, so the conversion is
  // what moves it onto FRD +x.
  auto frd = load_model(source("box.gltf", ModelAxes::frd()));
  ASSERT_TRUE(frd) << frd.error().message;
  expect_near(frd->bounds().first, {-1.0f, -0.5f, 1.5f});
  expect_near(frd->bounds().second, {0.0f, 0.0f, 2.5f});
  auto gl = load_model(source("box.gltf"));
  ASSERT_TRUE(gl);
  const Vector3f centre = 0.5f * (gl->bounds().first + gl->bounds().second);
  EXPECT_NEAR(centre.x(), 2.0f, 1e-5f);
}

TEST(LoadGltf, BinaryTwoMeshesNormalsScaleAndImageInBufferView) {
  auto model = load_model(source("box.glb", ModelAxes::gltf(), 0.5));
  ASSERT_TRUE(model) << model.error().message;
  ASSERT_EQ(model->meshes.size(), 2u);  // one Mesh per primitive
  const Mesh& box = model->meshes[0];
  const Mesh& tri = model->meshes[1];
  EXPECT_EQ(box.positions_m.size(), 24u);
  EXPECT_EQ(box.triangle_count(), 12u);
  EXPECT_EQ(tri.positions_m.size(), 3u);
  EXPECT_EQ(tri.triangle_count(), 1u);
  // Box scaled 2 by its node, 0.5 by the source: file x [0,1] y [0,0.5] z [-0.5,0.5] again.
  expect_near(box.bounds().first, {-0.5f, -1.0f, -0.5f});
  expect_near(box.bounds().second, {0.5f, 0.0f, 0.0f});
  // Triangle (0,0,0) (1,0,0) (0,1,0) + (0,3,0), times 0.5: FRD x 0, y [-0.5,0], z [-2,-1.5].
  expect_near(tri.bounds().first, {0.0f, -0.5f, -2.0f});
  expect_near(tri.bounds().second, {0.0f, 0.0f, -1.5f});
  // File normals are converted with the axes: the file's +y face points FRD -z.
  for (std::size_t i = 0; i < box.positions_m.size(); ++i) {
    EXPECT_NEAR(box.normals[i].norm(), 1.0f, 1e-5f);
    if (std::abs(box.positions_m[i].z() - (-0.5f)) < 1e-6f && box.normals[i].z() < -0.5f) {
      expect_near(box.normals[i], {0, 0, -1});
    }
  }
  EXPECT_GT(signed_volume(box), 0.0);
  // No material: default colour, no texture; box material: texture from the GLB buffer.
  EXPECT_FALSE(tri.texture);
  ASSERT_TRUE(box.texture);
  EXPECT_EQ(texel(*box.texture, 0.1f, 0.1f), (std::array<int, 4>{255, 0, 0, 255}));
  EXPECT_EQ(texel(*box.texture, 0.1f, 0.9f), (std::array<int, 4>{0, 0, 255, 255}));
}

TEST(LoadObj, ExplicitAxesScaleMaterialsAndTexture) {
  // File: centimetres, -z forward, +x right, +y up.
  auto model = load_model(source("textured.obj", ModelAxes{"-z", "+x", "-y"}, 0.01));
  ASSERT_TRUE(model) << model.error().message;
  ASSERT_EQ(model->meshes.size(), 2u);  // one Mesh per material
  const Mesh* quad = nullptr;
  const Mesh* tri = nullptr;
  for (const auto& m : model->meshes) (m.name == "painted" ? quad : tri) = &m;
  ASSERT_TRUE(quad && tri);
  EXPECT_EQ(tri->name, "plain");
  EXPECT_EQ(quad->positions_m.size(), 4u);
  EXPECT_EQ(quad->triangle_count(), 2u);  // the quad face is triangulated
  EXPECT_EQ(tri->positions_m.size(), 3u);
  EXPECT_EQ(tri->triangle_count(), 1u);
  expect_near(model->bounds().first, {0, 0, -1});
  expect_near(model->bounds().second, {1, 1, 0});
  expect_near(quad->bounds().first, {1, 0, -0.5f});
  expect_near(quad->bounds().second, {1, 1, 0});
  // Quad faces file +z (CCW seen from +z): FRD x = -file z, so its normal is FRD -x.
  for (const auto& n : quad->normals) expect_near(n, {-1, 0, 0});
  // Kd and map_Kd.
  expect_near(tri->base_color, {0.1f, 0.5f, 0.9f});
  EXPECT_FALSE(tri->texture);
  EXPECT_TRUE(tri->uvs.empty());
  ASSERT_TRUE(quad->texture);
  ASSERT_EQ(quad->uvs.size(), 4u);
  // OBJ vt (0,0) is the bottom-left of the image: at the file's (0,0,-100) = FRD (1,0,0) the uv
  // must be (0,1) and sample the bottom-left (blue) texel; vt (0,1) at FRD (1,0,-0.5) the top-left (red).
  for (std::size_t i = 0; i < 4; ++i) {
    const Vector3f& p = quad->positions_m[i];
    const Eigen::Vector2f& uv = quad->uvs[i];
    // Sample slightly inside the quad from the corner.
    const Eigen::Vector2f inside(uv.x() < 0.5f ? 0.1f : 0.9f, uv.y() < 0.5f ? 0.1f : 0.9f);
    if (p.isApprox(Vector3f(1, 0, 0))) {
      EXPECT_TRUE(uv.isApprox(Eigen::Vector2f(0, 1))) << uv.transpose();
      EXPECT_EQ(texel(*quad->texture, inside.x(), inside.y()), (std::array<int, 4>{0, 0, 255, 255}));
    }
    if ((p - Vector3f(1, 0, -0.5f)).norm() < 1e-6f) {
      EXPECT_TRUE(uv.isApprox(Eigen::Vector2f(0, 0), 1e-6f) || uv.norm() < 1e-6f) << uv.transpose();
      EXPECT_EQ(texel(*quad->texture, inside.x(), inside.y()), (std::array<int, 4>{255, 0, 0, 255}));
    }
  }
}

// Every broken input: an Error naming the loader and the file, with a hint of what went wrong.
struct BrokenCase {
  std::string file;
  std::string what;  // a fragment the message must contain (case-sensitive)
};

class BrokenFile : public ::testing::TestWithParam<BrokenCase> {};

TEST_P(BrokenFile, GivesAClearError) {
  const auto& c = GetParam();
  const std::string path = test::data_path("models/" + c.file);
  auto model = load_model(ModelSource{path, ModelAxes::gltf(), 1.0});
  ASSERT_FALSE(model) << c.file << " loaded";
  const std::string& msg = model.error().message;
  EXPECT_EQ(msg.rfind("mesh::load_model(): " + path + ": ", 0), 0u) << msg;
  EXPECT_NE(msg.find(c.what), std::string::npos) << "message: " << msg << "\nexpected to contain: " << c.what;
}

INSTANTIATE_TEST_SUITE_P(
    Loaders, BrokenFile,
    ::testing::Values(BrokenCase{"broken_truncated.glb", ""}, BrokenCase{"broken_text.glb", ""},
                      BrokenCase{"broken_random.glb", ""}, BrokenCase{"broken_random.gltf", ""},
                      BrokenCase{"broken_random.obj", ""}, BrokenCase{"broken_empty.gltf", ""},
                      BrokenCase{"broken_empty.glb", ""}, BrokenCase{"broken_empty.obj", "no triangles"},
                      BrokenCase{"broken_json.gltf", ""}, BrokenCase{"broken_index.obj", "out of range"},
                      BrokenCase{"broken_no_faces.obj", "no triangles"},
                      BrokenCase{"broken_missing_texture.obj", "not_there.png"},
                      BrokenCase{"broken_index.gltf", "out of range"},
                      BrokenCase{"broken_lines.gltf", "LINES"}, BrokenCase{"broken_nan.gltf", "non-finite"},
                      BrokenCase{"broken_accessor.gltf", ""},
                      BrokenCase{"broken_no_position.gltf", "POSITION"},
                      BrokenCase{"broken_cycle.gltf", "cyclic"}, BrokenCase{"broken_missing_buffer.gltf", ""},
                      BrokenCase{"broken_unknown.stl", "unknown extension"},
                      BrokenCase{"does_not_exist.gltf", "file not found"}),
    [](const ::testing::TestParamInfo<BrokenCase>& info) {
      std::string n = info.param.file;
      for (char& ch : n)
        if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
      return n;
    });

// tinyobjloader reads "nan" as 0 and 1e39 as inf (positions are float): both are errors naming
// the file and line, as glTF's non-finite values are.
TEST(LoadObj, NonFiniteNumbersNameTheLine) {
  for (const auto& [file, line, token] :
       {std::tuple<const char*, int, const char*>{"broken_nan.obj", 4, "nan"},
        {"broken_float_overflow.obj", 2, "1e39"}}) {
    const std::string path = test::data_path(std::string("models/") + file);
    auto model = load_model(ModelSource{path, ModelAxes::gltf(), 1.0});
    ASSERT_FALSE(model) << file;
    EXPECT_EQ(model.error().message,
              "mesh::load_model(): " + path + ":" + std::to_string(line) +
                  ": 'v' number 1: expected a finite number (within the float range), got '" + token + "'");
  }
}

// A missing material library is a warning naming it on stderr; the model loads with the default.
TEST(LoadObj, MissingMaterialLibraryWarnsAndLoads) {
  const std::string path = test::data_path("models/missing_mtllib.obj");
  testing::internal::CaptureStderr();
  auto model = load_model(ModelSource{path, ModelAxes::gltf(), 1.0});
  const std::string err = testing::internal::GetCapturedStderr();
  ASSERT_TRUE(model) << model.error().message;
  EXPECT_EQ(model->triangle_count(), 1u);
  EXPECT_NE(err.find("mesh::load_model(): " + path +
                     ":2: warning: material library 'no_such_library.mtl' not found"),
            std::string::npos)
      << err;
}

// A directory where the model file should be.
TEST(LoadModel, DirectoryIsNotAModel) {
  const std::string dir = test::output_dir("mesh_dir") + "/model.obj";
  std::filesystem::create_directories(dir);
  auto model = load_model(ModelSource{dir, ModelAxes::gltf(), 1.0});
  ASSERT_FALSE(model);
  EXPECT_EQ(model.error().message, "mesh::load_model(): " + dir + ": is a directory, expected a file");
}

TEST(LoadModel, BadAxesNameFileAndAxes) {
  const std::string path = test::data_path("models/box.gltf");
  const ModelAxes bad[] = {{"+z", "+z", "-y"}, {"+x", "+y", "-z"}, {"forward", "+y", "+z"}, {"+x", "+y", ""}};
  for (const auto& axes : bad) {
    auto model = load_model(ModelSource{path, axes, 1.0});
    ASSERT_FALSE(model);
    const std::string& msg = model.error().message;
    EXPECT_NE(msg.find("mesh::load_model(): " + path), std::string::npos) << msg;
    EXPECT_NE(msg.find("bad axes"), std::string::npos) << msg;
    EXPECT_NE(msg.find("forward=" + axes.forward), std::string::npos) << msg;
  }
  // Every proper rotation (24 of them) is accepted.
  const char* names[] = {"+x", "-x", "+y", "-y", "+z", "-z"};
  int accepted = 0;
  for (auto f : names)
    for (auto r : names)
      for (auto d : names) accepted += load_model(ModelSource{path, {f, r, d}, 1.0}).has_value();
  EXPECT_EQ(accepted, 24);
}

TEST(LoadModel, BadScaleAndEmptyPath) {
  const std::string path = test::data_path("models/box.gltf");
  for (double s : {0.0, -1.0, std::nan("")}) {
    auto model = load_model(ModelSource{path, ModelAxes::gltf(), s});
    ASSERT_FALSE(model);
    EXPECT_NE(model.error().message.find("scale"), std::string::npos);
  }
  auto model = load_model(ModelSource{});
  ASSERT_FALSE(model);
  EXPECT_EQ(model.error().message.rfind("mesh::load_model(): ", 0), 0u);
}

// ---- Metallic and roughness (issue 33: the boom's material from its model) ----

// A glTF with one triangle drawn by one primitive per material in `materials` (a JSON array's
// contents) plus one primitive without a material; written to a test folder, its path returned.
// `extra`: more top-level members, each followed by a comma ("textures": [...], ...).
std::string write_gltf(const std::string& name, const std::string& materials, int n_materials,
                       const std::string& extra = "") {
  std::string prims;
  for (int i = 0; i < n_materials; ++i)
    prims += R"({"attributes": {"POSITION": 0}, "material": )" + std::to_string(i) + "}, ";
  prims += R"({"attributes": {"POSITION": 0}})";
  const std::string json = R"({"asset": {"version": "2.0"}, )" + extra +
                           R"("scene": 0, "scenes": [{"nodes": [0]}],
  "nodes": [{"mesh": 0}], "meshes": [{"primitives": [)" +
                           prims + R"(]}],
  "materials": [)" + materials +
                           R"(],
  "buffers": [{"byteLength": 36, "uri": "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}],
  "bufferViews": [{"buffer": 0, "byteLength": 36}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                 "min": [0, 0, 0], "max": [1, 1, 0]}]})";
  const std::string path = test::output_dir("mesh_finish") + "/" + name;
  std::ofstream(path) << json;
  return path;
}

TEST(LoadGltf, MetallicAndRoughnessFromEachMaterialAndTheSpecsDefaults) {
  const std::string path =
      write_gltf("finishes.gltf",
                 R"({"name": "brass", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.6, 0.2, 1],
                                           "metallicFactor": 1.0, "roughnessFactor": 0.25}},
                                         {"name": "paint", "pbrMetallicRoughness": {"metallicFactor": 0, "roughnessFactor": 0.6}},
                                         {"name": "factors left out", "pbrMetallicRoughness": {}},
                                         {"name": "no pbr block"})",
                 4);
  auto model = load_model(ModelSource{path, ModelAxes::gltf(), 1.0});
  ASSERT_TRUE(model) << model.error().message;
  ASSERT_EQ(model->meshes.size(), 5u);
  const SurfaceFinish want[] = {{1.0, 0.25}, {0.0, 0.6}, {1.0, 1.0}, {1.0, 1.0}};
  for (int i = 0; i < 4; ++i) {
    EXPECT_TRUE(model->meshes[i].finish_from_file) << i;
    EXPECT_DOUBLE_EQ(model->meshes[i].finish.metallic, want[i].metallic) << i;
    EXPECT_DOUBLE_EQ(model->meshes[i].finish.roughness, want[i].roughness) << i;
  }
  expect_near(model->meshes[0].base_color, {0.9f, 0.6f, 0.2f});
  // No material: the built-in paint until the rig's boom.material says otherwise.
  EXPECT_FALSE(model->meshes[4].finish_from_file);
  EXPECT_EQ(model->meshes[4].finish, kPaintedBoom);
}

// A metallicRoughnessTexture (green: roughness, blue: metallic) scales the factors by its mean over
// the image: the renderers shade a mesh with one finish. A texture that does not exist is an error
// naming it.
TEST(LoadGltf, MetallicRoughnessTextureScalesTheFactorsByItsMean) {
  const std::string material =
      R"({"name": "worn", "pbrMetallicRoughness": {"metallicFactor": 0.8, "roughnessFactor": 1.0,
          "metallicRoughnessTexture": {"index": 0}}})";
  const std::string path = write_gltf("textured_finish.gltf", material, 1,
                                      R"("textures": [{"source": 0}], "images": [{"uri": "mr.png"}], )");
  // 2x2 texels: green 64, 128, 192, 255 (mean 159.75); blue 0, 255, 255, 0 (mean 127.5); red unused.
  cv::Mat texels(2, 2, CV_8UC3);
  texels.at<cv::Vec3b>(0, 0) = {0, 64, 200};  // OpenCV's order: blue, green, red
  texels.at<cv::Vec3b>(0, 1) = {255, 128, 10};
  texels.at<cv::Vec3b>(1, 0) = {255, 192, 30};
  texels.at<cv::Vec3b>(1, 1) = {0, 255, 90};
  ASSERT_TRUE(cv::imwrite((std::filesystem::path(path).parent_path() / "mr.png").string(), texels));
  auto model = load_model(ModelSource{path, ModelAxes::gltf(), 1.0});
  ASSERT_TRUE(model) << model.error().message;
  ASSERT_EQ(model->meshes.size(), 2u);
  EXPECT_TRUE(model->meshes[0].finish_from_file);
  EXPECT_NEAR(model->meshes[0].finish.metallic, 0.8 * 127.5 / 255.0, 1e-12);
  EXPECT_NEAR(model->meshes[0].finish.roughness, 159.75 / 255.0, 1e-12);

  const std::string bad =
      write_gltf("bad_texture.gltf",
                 R"({"name": "lost", "pbrMetallicRoughness": {"metallicRoughnessTexture": {"index": 3}}})", 1,
                 R"("textures": [{"source": 0}], "images": [{"uri": "mr.png"}], )");
  auto refused = load_model(ModelSource{bad, ModelAxes::gltf(), 1.0});
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find(bad), std::string::npos) << refused.error().message;
  EXPECT_NE(refused.error().message.find("metallicRoughnessTexture 3 does not exist"), std::string::npos)
      << refused.error().message;
}

TEST(LoadGltf, MetallicOrRoughnessOutOfRangeNamesTheFileAndMaterial) {
  for (const auto& [pbr, what] :
       {std::pair<std::string, std::string>{R"("metallicFactor": 1.5)", "metallicFactor 1.5"},
        {R"("roughnessFactor": -0.25)", "roughnessFactor -0.25"}}) {
    const std::string path = write_gltf(
        "bad_finish.gltf", R"({"name": "ok"}, {"name": "hot", "pbrMetallicRoughness": {)" + pbr + "}}", 2);
    auto model = load_model(ModelSource{path, ModelAxes::gltf(), 1.0});
    ASSERT_FALSE(model) << pbr;
    EXPECT_EQ(model.error().message, "mesh::load_model(): " + path +
                                         ": material 1 'hot': pbrMetallicRoughness: " + what +
                                         " is outside [0, 1]");
  }
}

// An OBJ material's Pm and Pr, or Ns as a Blinn-Phong exponent of the same lobe width; one with
// none of them is left to the rig (not from the file).
TEST(LoadObj, MetallicAndRoughnessFromPmPrAndNs) {
  const std::string dir = test::output_dir("mesh_finish_obj");
  std::ofstream(dir + "/m.mtl") << "newmtl pbr\nKd 0.5 0.5 0.5\nPm 1\nPr 0.3\n"
                                   "newmtl phong\nKd 0.5 0.5 0.5\nNs 30\n"
                                   "newmtl matte\nKd 0.5 0.5 0.5\n";
  std::ofstream(dir + "/m.obj") << "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                                   "usemtl pbr\nf 1 2 3\nusemtl phong\nf 1 3 2\nusemtl matte\nf 2 1 3\n";
  auto model = load_model(ModelSource{dir + "/m.obj", ModelAxes::frd(), 1.0});
  ASSERT_TRUE(model) << model.error().message;
  ASSERT_EQ(model->meshes.size(), 3u);
  for (const Mesh& m : model->meshes) {
    SCOPED_TRACE(m.name);
    if (m.name == "pbr") {
      EXPECT_TRUE(m.finish_from_file);
      EXPECT_EQ(m.finish, (SurfaceFinish{1.0, 0.3}));
    } else if (m.name == "phong") {
      // alpha^2 = 2 / (Ns + 2) = 1 / 16: alpha 0.25, roughness 0.5; a Phong material is a dielectric.
      EXPECT_TRUE(m.finish_from_file);
      EXPECT_DOUBLE_EQ(m.finish.metallic, 0.0);
      EXPECT_NEAR(m.finish.roughness, 0.5, 1e-12);
    } else {
      EXPECT_EQ(m.name, "matte");
      EXPECT_FALSE(m.finish_from_file);
      EXPECT_EQ(m.finish, kPaintedBoom);
    }
  }
  std::ofstream(dir + "/m.mtl") << "newmtl pbr\nKd 0.5 0.5 0.5\n\nPr 1.5\n";
  model = load_model(ModelSource{dir + "/m.obj", ModelAxes::frd(), 1.0});
  ASSERT_FALSE(model);
  EXPECT_EQ(model.error().message, "mesh::load_model(): " + dir + "/m.obj: material 'pbr' (" + dir +
                                       "/m.mtl:4): 'Pr' must be a number in [0, 1], got '1.5'");
  std::ofstream(dir + "/m.mtl") << "newmtl phong\nNs -2\n";
  model = load_model(ModelSource{dir + "/m.obj", ModelAxes::frd(), 1.0});
  ASSERT_FALSE(model);
  EXPECT_NE(model.error().message.find("material 'phong'"), std::string::npos) << model.error().message;
  EXPECT_NE(model.error().message.find("'Ns' must be a finite number >= 0, got '-2'"), std::string::npos);
}

}  // namespace
}  // namespace augrig
