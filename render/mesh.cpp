// Mesh utilities and the glTF / OBJ loaders (render/mesh.hpp is the spec).
//
// Loaders validate everything they read themselves (accessor ranges, indices, finiteness) rather than
// trusting the parser: a model file is user input and a malformed one must give an Error, not a crash.

// stb_image and tinygltf are header-only; this is the one translation unit that compiles them.
// Debian installs stb under /usr/include/stb/, so include it from there and tell tinygltf not to.
// STB*_STATIC keeps the stb symbols local to this file (no clash if another module uses stb too).
#define STB_IMAGE_STATIC
#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_WRITE_STATIC
#define STB_IMAGE_WRITE_IMPLEMENTATION
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wunused-parameter"
#pragma GCC diagnostic ignored "-Wimplicit-fallthrough"
#pragma GCC diagnostic ignored "-Wunused-but-set-variable"
#include <stb/stb_image.h>
#include <stb/stb_image_write.h>
#define TINYGLTF_NO_INCLUDE_STB_IMAGE
#define TINYGLTF_NO_INCLUDE_STB_IMAGE_WRITE
#define TINYGLTF_IMPLEMENTATION
#include <tiny_gltf.h>
#pragma GCC diagnostic pop

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <tiny_obj_loader.h>

#include "render/mesh.hpp"

namespace augrig {

// ----------------------------------------------------------------------------------------------
// Mesh / Model basics

std::pair<Eigen::Vector3f, Eigen::Vector3f> Mesh::bounds() const {
  if (positions_m.empty()) return {Eigen::Vector3f::Zero(), Eigen::Vector3f::Zero()};
  Eigen::Vector3f lo = positions_m.front(), hi = positions_m.front();
  for (const auto& p : positions_m) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return {lo, hi};
}

std::size_t Model::triangle_count() const {
  std::size_t n = 0;
  for (const auto& m : meshes) n += m.triangle_count();
  return n;
}

std::pair<Eigen::Vector3f, Eigen::Vector3f> Model::bounds() const {
  bool any = false;
  Eigen::Vector3f lo = Eigen::Vector3f::Zero(), hi = Eigen::Vector3f::Zero();
  for (const auto& m : meshes) {
    if (m.positions_m.empty()) continue;
    const auto [mlo, mhi] = m.bounds();
    lo = any ? lo.cwiseMin(mlo) : mlo;
    hi = any ? hi.cwiseMax(mhi) : mhi;
    any = true;
  }
  return {lo, hi};
}

void compute_normals(Mesh& mesh) {
  const std::size_t n = mesh.positions_m.size();
  std::vector<Eigen::Vector3f> acc(n, Eigen::Vector3f::Zero());
  for (std::size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
    const std::uint32_t a = mesh.indices[t], b = mesh.indices[t + 1], c = mesh.indices[t + 2];
    if (a >= n || b >= n || c >= n) continue;  // tolerate bad input; load_model rejects it earlier
    // The unnormalised cross product has length 2*area: summing it weights faces by area.
    const Eigen::Vector3f fn =
        (mesh.positions_m[b] - mesh.positions_m[a]).cross(mesh.positions_m[c] - mesh.positions_m[a]);
    acc[a] += fn;
    acc[b] += fn;
    acc[c] += fn;
  }
  mesh.normals.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const float len = acc[i].norm();
    // A vertex with no (or only degenerate) faces still needs a unit normal: pick "up" (FRD -z).
    mesh.normals[i] = (len > 0.0f && std::isfinite(len)) ? Eigen::Vector3f(acc[i] / len)
                                                         : Eigen::Vector3f(0.0f, 0.0f, -1.0f);
  }
}

// ----------------------------------------------------------------------------------------------
// Shared loader helpers

namespace {

constexpr const char* kWhere = "mesh::load_model(): ";

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

// One of "+x" "-x" "+y" "-y" "+z" "-z" -> signed unit row; nullopt-like via `ok`.
bool parse_axis(const std::string& s, Eigen::RowVector3d* row) {
  if (s.size() != 2 || (s[0] != '+' && s[0] != '-')) return false;
  const int axis = (s[1] == 'x' || s[1] == 'X')   ? 0
                   : (s[1] == 'y' || s[1] == 'Y') ? 1
                   : (s[1] == 'z' || s[1] == 'Z') ? 2
                                                  : -1;
  if (axis < 0) return false;
  row->setZero();
  (*row)(axis) = s[0] == '+' ? 1.0 : -1.0;
  return true;
}

// R_frd_file: row i picks the file axis named by forward (i=0), right (1), down (2).
Expected<Eigen::Matrix3d> axes_rotation(const ModelAxes& axes, const std::string& path) {
  const std::string named = "forward=" + axes.forward + " right=" + axes.right + " down=" + axes.down;
  Eigen::Matrix3d R;
  const std::array<const std::string*, 3> names{&axes.forward, &axes.right, &axes.down};
  for (int i = 0; i < 3; ++i) {
    Eigen::RowVector3d row;
    if (!parse_axis(*names[i], &row)) {
      return make_error(kWhere, path, ": bad axes (", named, "): '", *names[i],
                        "' is not one of +x -x +y -y +z -z");
    }
    R.row(i) = row;
  }
  // Repeated axes give det 0, a mirror gives det -1: both would corrupt winding or collapse the model.
  const double det = R.determinant();
  if (std::abs(det - 1.0) > 1e-9) {
    return make_error(kWhere, path, ": bad axes (", named,
                      "): ", std::abs(det) < 0.5 ? "an axis is used twice" : "left-handed (a mirror)",
                      ", forward/right/down must form a right-handed frame");
  }
  return R;
}

bool all_finite(const Eigen::Vector3f& v) {
  return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z());
}

// Applies p_frd = scale * R * p_file (normals: R * n) to every mesh and checks the result.
Status convert_to_frd(Model& model, const Eigen::Matrix3d& R, double scale, const std::string& path) {
  const Eigen::Matrix3f Rf = R.cast<float>();
  const float s = static_cast<float>(scale);
  for (auto& mesh : model.meshes) {
    for (auto& p : mesh.positions_m) {
      p = s * (Rf * p);
      if (!all_finite(p)) return make_error(kWhere, path, ": ", mesh.name, ": non-finite vertex position");
    }
    for (auto& n : mesh.normals) n = Rf * n;
  }
  return {};
}

// Keeps supplied normals when they are all usable, otherwise recomputes them from the triangles.
void fix_normals(Mesh& mesh) {
  bool ok = mesh.normals.size() == mesh.positions_m.size();
  for (std::size_t i = 0; ok && i < mesh.normals.size(); ++i) {
    const float len = mesh.normals[i].norm();
    if (!(len > 1e-6f) || !std::isfinite(len)) {
      ok = false;
    } else {
      mesh.normals[i] /= len;
    }
  }
  if (!ok) compute_normals(mesh);
}

std::shared_ptr<const Texture> texture_from_mat(const cv::Mat& in) {
  cv::Mat img = in;
  if (img.depth() == CV_16U) img.convertTo(img, CV_8U, 1.0 / 257.0);
  if (img.depth() != CV_8U) img.convertTo(img, CV_8U);
  cv::Mat rgba;
  switch (img.channels()) {
    case 1:
      cv::cvtColor(img, rgba, cv::COLOR_GRAY2RGBA);
      break;
    case 3:
      cv::cvtColor(img, rgba, cv::COLOR_BGR2RGBA);
      break;
    case 4:
      cv::cvtColor(img, rgba, cv::COLOR_BGRA2RGBA);
      break;
    default:
      return nullptr;
  }
  auto tex = std::make_shared<Texture>();
  tex->width = rgba.cols;
  tex->height = rgba.rows;
  tex->rgba.resize(static_cast<std::size_t>(rgba.cols) * rgba.rows * 4);
  for (int r = 0; r < rgba.rows; ++r) {
    std::memcpy(tex->rgba.data() + static_cast<std::size_t>(r) * rgba.cols * 4, rgba.ptr(r),
                static_cast<std::size_t>(rgba.cols) * 4);
  }
  return tex;
}

// ----------------------------------------------------------------------------------------------
// glTF 2.0

struct GltfContext {
  const tinygltf::Model& gm;
  const std::string& path;
  std::map<int, std::shared_ptr<const Texture>> textures;  // by image index, shared between primitives
  std::set<int> noted_materials;  // materials whose averaged metallicRoughnessTexture was noted
};

int component_size(int type) {
  switch (type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return 2;
    case TINYGLTF_COMPONENT_TYPE_INT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return 4;
    default:
      return 0;
  }
}

int type_components(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR:
      return 1;
    case TINYGLTF_TYPE_VEC2:
      return 2;
    case TINYGLTF_TYPE_VEC3:
      return 3;
    case TINYGLTF_TYPE_VEC4:
      return 4;
    default:
      return 0;
  }
}

// Bytes of one accessor element, checked against its buffer view and buffer. `base` receives the
// address of element 0 (nullptr when the accessor has no buffer view: all zeros per the spec).
struct AccessorView {
  const unsigned char* base = nullptr;
  std::size_t stride = 0;
  std::size_t count = 0;
  int component_type = 0;
  int components = 0;
  bool normalized = false;
};

Expected<AccessorView> view_accessor(const GltfContext& ctx, int index, const std::string& what) {
  const auto& gm = ctx.gm;
  auto fail = [&](const std::string& why) { return make_error(kWhere, ctx.path, ": ", what, ": ", why); };
  if (index < 0 || index >= static_cast<int>(gm.accessors.size())) {
    return fail("accessor " + std::to_string(index) + " does not exist");
  }
  const auto& acc = gm.accessors[index];
  AccessorView v;
  v.count = acc.count;
  v.component_type = acc.componentType;
  v.components = type_components(acc.type);
  v.normalized = acc.normalized;
  const int csize = component_size(acc.componentType);
  if (csize == 0 || v.components == 0) return fail("accessor " + std::to_string(index) + " has a bad type");
  if (acc.sparse.isSparse) return fail("sparse accessors are not supported");
  const std::size_t elem = static_cast<std::size_t>(csize) * v.components;
  if (acc.bufferView < 0) {
    v.stride = elem;
    return v;
  }
  if (acc.bufferView >= static_cast<int>(gm.bufferViews.size())) {
    return fail("accessor " + std::to_string(index) + " names a missing bufferView");
  }
  const auto& bv = gm.bufferViews[acc.bufferView];
  if (bv.buffer < 0 || bv.buffer >= static_cast<int>(gm.buffers.size())) {
    return fail("bufferView " + std::to_string(acc.bufferView) + " names a missing buffer");
  }
  const auto& buf = gm.buffers[bv.buffer].data;
  v.stride = bv.byteStride == 0 ? elem : bv.byteStride;
  if (v.stride < elem) return fail("bufferView stride smaller than an element");
  // All in size_t after bounding each term by the buffer size, so nothing can overflow.
  if (bv.byteOffset > buf.size() || bv.byteLength > buf.size() - bv.byteOffset) {
    return fail("bufferView " + std::to_string(acc.bufferView) + " runs past the end of its buffer");
  }
  if (v.count > 0) {
    if (acc.byteOffset > bv.byteLength || v.count > bv.byteLength ||
        (v.count - 1) * v.stride + elem > bv.byteLength - acc.byteOffset) {
      return fail("accessor " + std::to_string(index) + " (" + std::to_string(v.count) +
                  " elements) runs past the end of its bufferView");
    }
  }
  v.base = buf.data() + bv.byteOffset + acc.byteOffset;
  return v;
}

// Component c of element i as a double (normalised integer types mapped to 0..1 / -1..1).
double read_component(const AccessorView& v, std::size_t i, int c) {
  if (v.base == nullptr) return 0.0;
  const unsigned char* p =
      v.base + i * v.stride + static_cast<std::size_t>(c) * component_size(v.component_type);
  auto get = [p](auto tag) {
    decltype(tag) x;
    std::memcpy(&x, p, sizeof x);  // glTF data need not be aligned
    return x;
  };
  switch (v.component_type) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return get(float{});
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: {
      const double x = get(std::uint8_t{});
      return v.normalized ? x / 255.0 : x;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      const double x = get(std::uint16_t{});
      return v.normalized ? x / 65535.0 : x;
    }
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      const double x = get(std::int8_t{});
      return v.normalized ? std::max(x / 127.0, -1.0) : x;
    }
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      const double x = get(std::int16_t{});
      return v.normalized ? std::max(x / 32767.0, -1.0) : x;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
      return get(std::uint32_t{});
    case TINYGLTF_COMPONENT_TYPE_INT:
      return get(std::int32_t{});
    default:
      return 0.0;
  }
}

// Texture `texture_index` (a material's `role`: "baseColorTexture", "metallicRoughnessTexture") as
// 8-bit RGBA, decoded once per image.
Expected<std::shared_ptr<const Texture>> gltf_texture(GltfContext& ctx, int texture_index,
                                                      const std::string& what,
                                                      const std::string& role = "baseColorTexture") {
  const auto& gm = ctx.gm;
  auto fail = [&](const std::string& why) { return make_error(kWhere, ctx.path, ": ", what, ": ", why); };
  if (texture_index < 0 || texture_index >= static_cast<int>(gm.textures.size())) {
    return fail(role + " " + std::to_string(texture_index) + " does not exist");
  }
  const int image_index = gm.textures[texture_index].source;
  if (image_index < 0 || image_index >= static_cast<int>(gm.images.size())) {
    return fail("texture " + std::to_string(texture_index) + " has no image");
  }
  if (auto it = ctx.textures.find(image_index); it != ctx.textures.end()) return it->second;
  const auto& img = gm.images[image_index];
  const int comp = img.component;
  const int bytes = img.bits / 8;
  if (img.width <= 0 || img.height <= 0 || comp < 1 || comp > 4 || (bytes != 1 && bytes != 2) ||
      img.image.size() < static_cast<std::size_t>(img.width) * img.height * comp * bytes) {
    return fail("image " + std::to_string(image_index) + " '" + img.uri + "' could not be decoded");
  }
  auto tex = std::make_shared<Texture>();
  tex->width = img.width;
  tex->height = img.height;
  tex->rgba.resize(static_cast<std::size_t>(img.width) * img.height * 4);
  const std::size_t n = static_cast<std::size_t>(img.width) * img.height;
  for (std::size_t i = 0; i < n; ++i) {
    auto ch = [&](int c) -> std::uint8_t {
      const unsigned char* p = img.image.data() + (i * comp + c) * bytes;
      if (bytes == 1) return *p;
      std::uint16_t x;
      std::memcpy(&x, p, 2);
      return static_cast<std::uint8_t>(x >> 8);
    };
    std::uint8_t* o = tex->rgba.data() + i * 4;
    if (comp <= 2) {
      o[0] = o[1] = o[2] = ch(0);
      o[3] = comp == 2 ? ch(1) : 255;
    } else {
      o[0] = ch(0);
      o[1] = ch(1);
      o[2] = ch(2);
      o[3] = comp == 4 ? ch(3) : 255;
    }
  }
  ctx.textures[image_index] = tex;
  return std::shared_ptr<const Texture>(tex);
}

const char* mode_name(int mode) {
  switch (mode) {
    case TINYGLTF_MODE_POINTS:
      return "POINTS";
    case TINYGLTF_MODE_LINE:
      return "LINES";
    case TINYGLTF_MODE_LINE_LOOP:
      return "LINE_LOOP";
    case TINYGLTF_MODE_LINE_STRIP:
      return "LINE_STRIP";
    case TINYGLTF_MODE_TRIANGLE_STRIP:
      return "TRIANGLE_STRIP";
    case TINYGLTF_MODE_TRIANGLE_FAN:
      return "TRIANGLE_FAN";
    default:
      return "unknown";
  }
}

// glTF's metallicRoughnessTexture: roughness in its green channel, metallic in its blue, each
// multiplied by its factor. One finish per mesh: the texels' mean (linear values, as the spec has
// them), so a texture that varies over the surface gives its average finish rather than none.
SurfaceFinish averaged_finish(const Texture& t, const SurfaceFinish& factors) {
  double green = 0, blue = 0;
  const std::size_t n = static_cast<std::size_t>(t.width) * static_cast<std::size_t>(t.height);
  for (std::size_t i = 0; i < n; ++i) {
    green += t.rgba[i * 4 + 1];
    blue += t.rgba[i * 4 + 2];
  }
  const double scale = 1.0 / (255.0 * static_cast<double>(std::max<std::size_t>(n, 1)));
  return SurfaceFinish{factors.metallic * blue * scale, factors.roughness * green * scale};
}

// A primitive's material into `mesh`: base colour factor and texture, metallic and roughness
// (tinygltf gives the spec's defaults, 1 and 1, for factors the file leaves out). Returns the
// TEXCOORD set the base colour texture names.
Expected<int> gltf_material(GltfContext& ctx, int index, const std::string& what, Mesh& mesh) {
  const tinygltf::Material& mat = ctx.gm.materials[index];
  const std::string name =
      "material " + std::to_string(index) + (mat.name.empty() ? "" : " '" + mat.name + "'");
  const auto& pbr = mat.pbrMetallicRoughness;
  if (pbr.baseColorFactor.size() >= 3) {
    mesh.base_color = Eigen::Vector3f(static_cast<float>(pbr.baseColorFactor[0]),
                                      static_cast<float>(pbr.baseColorFactor[1]),
                                      static_cast<float>(pbr.baseColorFactor[2]));
  }
  int texcoord_set = 0;
  if (pbr.baseColorTexture.index >= 0) {
    auto tex = gltf_texture(ctx, pbr.baseColorTexture.index, what);
    if (!tex) return tex.error();
    mesh.texture = *tex;
    texcoord_set = pbr.baseColorTexture.texCoord;
  }
  mesh.finish = SurfaceFinish{pbr.metallicFactor, pbr.roughnessFactor};
  mesh.finish_from_file = true;
  if (const std::string why = finish_problem(mesh.finish, "metallicFactor", "roughnessFactor"); !why.empty())
    return make_error(kWhere, ctx.path, ": ", name, ": pbrMetallicRoughness: ", why);
  if (pbr.metallicRoughnessTexture.index >= 0) {
    auto tex = gltf_texture(ctx, pbr.metallicRoughnessTexture.index, what, "metallicRoughnessTexture");
    if (!tex) return tex.error();
    mesh.finish = averaged_finish(**tex, mesh.finish);
    // The renderers shade a mesh with one finish: the texture's mean, said once per material.
    if (ctx.noted_materials.insert(index).second)
      std::fprintf(stderr,
                   "%s%s: note: %s: metallicRoughnessTexture averaged over its image: metallic %.3f, "
                   "roughness %.3f for the whole mesh\n",
                   kWhere, ctx.path.c_str(), name.c_str(), mesh.finish.metallic, mesh.finish.roughness);
  }
  return texcoord_set;
}

// One primitive -> one Mesh, positions and normals in the glTF scene frame (node transform applied).
Expected<Mesh> gltf_primitive(GltfContext& ctx, int mesh_index, int prim_index, const Eigen::Matrix4d& M) {
  const auto& gm = ctx.gm;
  const auto& gmesh = gm.meshes[mesh_index];
  const auto& prim = gmesh.primitives[prim_index];
  const std::string what = "mesh " + std::to_string(mesh_index) +
                           (gmesh.name.empty() ? "" : " '" + gmesh.name + "'") + " primitive " +
                           std::to_string(prim_index);
  auto fail = [&](const std::string& why) { return make_error(kWhere, ctx.path, ": ", what, ": ", why); };

  // mode -1 is tinygltf's "absent", which the spec defines as TRIANGLES.
  if (prim.mode != -1 && prim.mode != TINYGLTF_MODE_TRIANGLES) {
    return fail("mode " + std::to_string(prim.mode) + " (" + mode_name(prim.mode) +
                ") is not supported, only TRIANGLES");
  }
  Mesh mesh;
  mesh.name = (gmesh.name.empty() ? "mesh" + std::to_string(mesh_index) : gmesh.name) + "/" +
              std::to_string(prim_index);

  const auto pos_it = prim.attributes.find("POSITION");
  if (pos_it == prim.attributes.end()) return fail("no POSITION attribute");
  auto pos = view_accessor(ctx, pos_it->second, what + " POSITION");
  if (!pos) return pos.error();
  if (pos->components != 3 || pos->component_type != TINYGLTF_COMPONENT_TYPE_FLOAT) {
    return fail("POSITION must be a float VEC3 accessor");
  }
  const std::size_t nv = pos->count;
  const Eigen::Matrix3d L = M.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = M.topRightCorner<3, 1>();
  mesh.positions_m.resize(nv);
  for (std::size_t i = 0; i < nv; ++i) {
    const Eigen::Vector3d p(read_component(*pos, i, 0), read_component(*pos, i, 1),
                            read_component(*pos, i, 2));
    mesh.positions_m[i] = (L * p + t).cast<float>();
    if (!all_finite(mesh.positions_m[i])) return fail("non-finite vertex position " + std::to_string(i));
  }

  if (const auto it = prim.attributes.find("NORMAL"); it != prim.attributes.end()) {
    auto nrm = view_accessor(ctx, it->second, what + " NORMAL");
    if (!nrm) return nrm.error();
    if (nrm->components != 3 || nrm->count != nv) return fail("NORMAL must be VEC3 with one per position");
    // Normals transform with the inverse transpose (node scale may be non-uniform).
    const Eigen::Matrix3d N = L.inverse().transpose();
    mesh.normals.resize(nv);
    for (std::size_t i = 0; i < nv; ++i) {
      const Eigen::Vector3d n(read_component(*nrm, i, 0), read_component(*nrm, i, 1),
                              read_component(*nrm, i, 2));
      mesh.normals[i] = (N * n).cast<float>();
    }
  }

  // Material: base colour factor and texture (which names its TEXCOORD set), metallic, roughness.
  int texcoord_set = 0;
  if (prim.material >= 0) {
    if (prim.material >= static_cast<int>(gm.materials.size())) return fail("material does not exist");
    auto set = gltf_material(ctx, prim.material, what, mesh);
    if (!set) return set.error();
    texcoord_set = *set;
  }
  if (const auto it = prim.attributes.find("TEXCOORD_" + std::to_string(texcoord_set));
      it != prim.attributes.end()) {
    auto tc = view_accessor(ctx, it->second, what + " TEXCOORD");
    if (!tc) return tc.error();
    if (tc->components != 2 || tc->count != nv) return fail("TEXCOORD must be VEC2 with one per position");
    mesh.uvs.resize(nv);
    // glTF texture coordinates already have v down from the top-left of the image: no flip.
    for (std::size_t i = 0; i < nv; ++i) {
      mesh.uvs[i] = Eigen::Vector2f(static_cast<float>(read_component(*tc, i, 0)),
                                    static_cast<float>(read_component(*tc, i, 1)));
    }
  }
  if (mesh.uvs.empty()) mesh.texture = nullptr;  // a texture without coordinates cannot be mapped

  // Indices (or implicit 0..n-1).
  if (prim.indices >= 0) {
    auto idx = view_accessor(ctx, prim.indices, what + " indices");
    if (!idx) return idx.error();
    if (idx->components != 1 || (idx->component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
                                 idx->component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
                                 idx->component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)) {
      return fail("indices must be unsigned byte/short/int scalars");
    }
    mesh.indices.resize(idx->count);
    for (std::size_t i = 0; i < idx->count; ++i) {
      const double x = read_component(*idx, i, 0);
      if (x >= static_cast<double>(nv)) {
        return fail("index " + std::to_string(static_cast<std::uint64_t>(x)) + " out of range (" +
                    std::to_string(nv) + " vertices)");
      }
      mesh.indices[i] = static_cast<std::uint32_t>(x);
    }
  } else {
    if (nv > std::numeric_limits<std::uint32_t>::max()) return fail("too many vertices");
    mesh.indices.resize(nv);
    for (std::size_t i = 0; i < nv; ++i) mesh.indices[i] = static_cast<std::uint32_t>(i);
  }
  if (mesh.indices.size() % 3 != 0) {
    return fail(std::to_string(mesh.indices.size()) + " indices is not a whole number of triangles");
  }
  // A mirroring node transform turns the winding inside out; swap two corners to keep it CCW-outside.
  if (L.determinant() < 0) {
    for (std::size_t i = 0; i + 2 < mesh.indices.size(); i += 3)
      std::swap(mesh.indices[i + 1], mesh.indices[i + 2]);
  }
  fix_normals(mesh);
  return mesh;
}

Eigen::Matrix4d node_local(const tinygltf::Node& node) {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  if (node.matrix.size() == 16) {
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) T(r, c) = node.matrix[c * 4 + r];  // column-major
    return T;
  }
  if (node.translation.size() == 3) T.topRightCorner<3, 1>() = Eigen::Vector3d(node.translation.data());
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  if (node.rotation.size() == 4) {  // glTF order x y z w
    Eigen::Quaterniond q(node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]);
    if (q.norm() > 0) R = q.normalized().toRotationMatrix();
  }
  Eigen::Vector3d s = Eigen::Vector3d::Ones();
  if (node.scale.size() == 3) s = Eigen::Vector3d(node.scale.data());
  T.topLeftCorner<3, 3>() = R * s.asDiagonal();
  return T;
}

Status gltf_node(GltfContext& ctx, int node_index, const Eigen::Matrix4d& parent, std::vector<int>& stack,
                 Model& out) {
  const auto& gm = ctx.gm;
  if (node_index < 0 || node_index >= static_cast<int>(gm.nodes.size())) {
    return make_error(kWhere, ctx.path, ": node ", node_index, " does not exist");
  }
  // A cyclic hierarchy would recurse forever; a deep one could overflow the stack.
  if (std::find(stack.begin(), stack.end(), node_index) != stack.end() || stack.size() > 256) {
    return make_error(kWhere, ctx.path, ": node hierarchy is cyclic or deeper than 256 at node ", node_index);
  }
  const auto& node = gm.nodes[node_index];
  const Eigen::Matrix4d M = parent * node_local(node);
  if (!M.allFinite())
    return make_error(kWhere, ctx.path, ": node ", node_index, " has a non-finite transform");
  if (node.mesh >= 0) {
    if (node.mesh >= static_cast<int>(gm.meshes.size())) {
      return make_error(kWhere, ctx.path, ": node ", node_index, " names missing mesh ", node.mesh);
    }
    for (int p = 0; p < static_cast<int>(gm.meshes[node.mesh].primitives.size()); ++p) {
      auto mesh = gltf_primitive(ctx, node.mesh, p, M);
      if (!mesh) return mesh.error();
      out.meshes.push_back(std::move(*mesh));
    }
  }
  stack.push_back(node_index);
  for (int child : node.children) {
    if (auto st = gltf_node(ctx, child, M, stack, out); !st) return st;
  }
  stack.pop_back();
  return {};
}

Expected<Model> load_gltf(const std::string& path, bool binary) {
  tinygltf::TinyGLTF loader;
  tinygltf::Model gm;
  std::string err, warn;
  bool ok = false;
  try {
    ok = binary ? loader.LoadBinaryFromFile(&gm, &err, &warn, path)
                : loader.LoadASCIIFromFile(&gm, &err, &warn, path);
  } catch (const std::exception& e) {
    return make_error(kWhere, path, ": glTF parse failed: ", e.what());
  }
  if (!ok) {
    std::string what = err.empty() ? "glTF parse failed" : "glTF parse failed: " + err;
    if (!warn.empty()) what += " (warnings: " + warn + ")";
    while (!what.empty() && (what.back() == '\n' || what.back() == ' ')) what.pop_back();
    return make_error(kWhere, path, ": ", what);
  }

  GltfContext ctx{gm, path, {}, {}};
  Model model;
  std::vector<int> roots;
  if (!gm.scenes.empty()) {
    const int s =
        gm.defaultScene >= 0 && gm.defaultScene < static_cast<int>(gm.scenes.size()) ? gm.defaultScene : 0;
    roots = gm.scenes[s].nodes;
  } else {
    // No scene: take every node that is nobody's child.
    std::set<int> children;
    for (const auto& n : gm.nodes) children.insert(n.children.begin(), n.children.end());
    for (int i = 0; i < static_cast<int>(gm.nodes.size()); ++i)
      if (!children.count(i)) roots.push_back(i);
  }
  std::vector<int> stack;
  for (int r : roots) {
    if (auto st = gltf_node(ctx, r, Eigen::Matrix4d::Identity(), stack, model); !st) return st.error();
  }
  return model;
}

// ----------------------------------------------------------------------------------------------
// Wavefront OBJ

// What tinyobjloader lets through silently, checked on the text so messages can name the line:
// it reads a number it cannot parse ("nan", "inf", "abc") as 0 and a float-overflowing one as inf,
// and it only notes a missing material library among its warnings. Non-finite or unparsable
// v/vn/vt numbers are an Error; a missing mtllib is a warning on stderr (the model still loads,
// with the default material). `dir` is where tinyobjloader looks for the .mtl files.
Expected<std::vector<std::filesystem::path>> check_obj_text(const std::string& path,
                                                            const std::filesystem::path& dir) {
  namespace fs = std::filesystem;
  std::ifstream in(path, std::ios::binary);
  if (!in) return make_error(kWhere, path, ": cannot open the file (", std::strerror(errno), ")");
  std::vector<fs::path> libraries;
  std::string line;
  for (std::size_t no = 1; std::getline(in, line); ++no) {
    std::istringstream ls(line.substr(0, line.find('#')));
    std::string key;
    if (!(ls >> key)) continue;
    if (key == "v" || key == "vn" || key == "vt") {
      std::string tok;
      for (int i = 1; ls >> tok; ++i) {
        errno = 0;
        char* end = nullptr;
        const double v = std::strtod(tok.c_str(), &end);
        // Positions are stored as float: beyond its range they would become inf.
        if (end != tok.c_str() + tok.size() || !std::isfinite(v) ||
            std::abs(v) > static_cast<double>(std::numeric_limits<float>::max())) {
          return make_error(kWhere, path, ":", no, ": '", key, "' number ", i,
                            ": expected a finite number (within the float range), got '", tok.substr(0, 40),
                            "'");
        }
      }
    } else if (key == "mtllib") {
      std::string name;
      while (ls >> name) {
        const fs::path p = fs::path(name).is_absolute() ? fs::path(name) : dir / name;
        std::error_code ec;
        if (fs::is_regular_file(p, ec)) {
          libraries.push_back(p);
        } else {
          std::fprintf(
              stderr, "%s%s:%zu: warning: material library '%s' %s (%s): using the default material\n",
              kWhere, path.c_str(), no, name.c_str(),
              fs::is_directory(p, ec) ? "is a directory, expected a file" : "not found", p.string().c_str());
        }
      }
    }
  }
  if (in.bad()) return make_error(kWhere, path, ": read error");
  return libraries;
}

// An OBJ material's metallic and roughness keys as its .mtl gives them (NaN: absent): PBR's Pm
// and Pr, and Phong's shininess Ns.
struct MtlFinish {
  double pm = NAN, pr = NAN, ns = NAN;
  bool any() const { return !std::isnan(pm) || !std::isnan(pr) || !std::isnan(ns); }
  // Pr, else Ns as the Blinn-Phong exponent of the same lobe width (alpha^2 = 2 / (Ns + 2),
  // alpha = roughness^2), else the built-in paint's; Pm, else 0 (a Phong material is a dielectric).
  SurfaceFinish finish() const {
    const double r = !std::isnan(pr)   ? pr
                     : !std::isnan(ns) ? std::pow(2.0 / (ns + 2.0), 0.25)
                                       : kPaintedBoom.roughness;
    return {std::isnan(pm) ? 0.0 : pm, r};
  }
};

// The Pm, Pr and Ns keys of every material of the OBJ's libraries, by material name (the first
// definition of a name, as tinyobjloader keeps it), read here because tinyobjloader fills absent
// ones with values of its own. A value out of its range (Pm, Pr: [0, 1]; Ns: >= 0) is an Error
// naming the OBJ, the material, and the library's line.
Expected<std::map<std::string, MtlFinish>> mtl_finishes(const std::string& path,
                                                        const std::vector<std::filesystem::path>& libraries) {
  std::map<std::string, MtlFinish> out;
  for (const std::filesystem::path& lib : libraries) {
    std::ifstream in(lib, std::ios::binary);
    std::string line, name;
    std::set<std::string> here;  // defined in this library (a name defined earlier keeps its keys)
    for (std::size_t no = 1; std::getline(in, line); ++no) {
      std::istringstream ls(line.substr(0, line.find('#')));
      std::string key, tok;
      if (!(ls >> key)) continue;
      if (key == "newmtl") {
        name.clear();
        ls >> name;
        if (!out.count(name)) here.insert(name), out[name] = {};
        continue;
      }
      if ((key != "Pm" && key != "Pr" && key != "Ns") || !here.count(name)) continue;
      ls >> tok;
      char* end = nullptr;
      const double x = std::strtod(tok.c_str(), &end);
      const bool unit = key != "Ns";
      if (tok.empty() || end != tok.c_str() + tok.size() || !(x >= 0.0) || (unit && x > 1.0) ||
          !std::isfinite(x))
        return make_error(kWhere, path, ": material '", name, "' (", lib.string(), ":", no, "): '", key,
                          unit ? "' must be a number in [0, 1]" : "' must be a finite number >= 0", ", got '",
                          tok.substr(0, 40), "'");
      (key == "Pm" ? out[name].pm : key == "Pr" ? out[name].pr : out[name].ns) = x;
    }
  }
  return out;
}

Expected<Model> load_obj(const std::string& path) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(path).parent_path();
  auto libraries = check_obj_text(path, dir);
  if (!libraries) return libraries.error();
  auto finishes = mtl_finishes(path, *libraries);
  if (!finishes) return finishes.error();
  tinyobj::ObjReaderConfig config;
  // We fan-triangulate ourselves after validating indices: tinyobjloader's own triangulation reads
  // vertex positions through unchecked face indices.
  config.triangulate = false;
  config.vertex_color = false;
  config.mtl_search_path = dir.string();
  tinyobj::ObjReader reader;
  bool ok = false;
  try {
    ok = reader.ParseFromFile(path, config);
  } catch (const std::exception& e) {
    return make_error(kWhere, path, ": OBJ parse failed: ", e.what());
  }
  if (!ok) {
    std::string what = reader.Error().empty() ? "OBJ parse failed" : "OBJ parse failed: " + reader.Error();
    while (!what.empty() && (what.back() == '\n' || what.back() == ' ')) what.pop_back();
    return make_error(kWhere, path, ": ", what);
  }
  const auto& attrib = reader.GetAttrib();
  const auto& materials = reader.GetMaterials();
  const long nv = static_cast<long>(attrib.vertices.size() / 3);
  const long nn = static_cast<long>(attrib.normals.size() / 3);
  const long nt = static_cast<long>(attrib.texcoords.size() / 2);

  // One Mesh per material (material id -1: no material), across all shapes.
  struct Group {
    Mesh mesh;
    std::map<std::array<int, 3>, std::uint32_t> remap;  // (v, vt, vn) -> vertex
    bool all_normals = true;
    bool any_uv = false;
  };
  std::map<int, Group> groups;
  std::map<std::string, std::shared_ptr<const Texture>> textures;

  for (const auto& shape : reader.GetShapes()) {
    std::size_t offset = 0;
    for (std::size_t f = 0; f < shape.mesh.num_face_vertices.size(); ++f) {
      const std::size_t fv = shape.mesh.num_face_vertices[f];
      if (offset + fv > shape.mesh.indices.size())
        return make_error(kWhere, path, ": inconsistent face list");
      int mat = f < shape.mesh.material_ids.size() ? shape.mesh.material_ids[f] : -1;
      if (mat < -1 || mat >= static_cast<int>(materials.size())) mat = -1;
      Group& g = groups[mat];
      std::vector<std::uint32_t> corners;
      for (std::size_t k = 0; k < fv; ++k) {
        const auto& ix = shape.mesh.indices[offset + k];
        if (ix.vertex_index < 0 || ix.vertex_index >= nv || ix.normal_index < -1 || ix.normal_index >= nn ||
            ix.texcoord_index < -1 || ix.texcoord_index >= nt) {
          return make_error(kWhere, path, ": ", shape.name.empty() ? "" : "object '" + shape.name + "' ",
                            "face ", f + 1, ": index out of range (v ", ix.vertex_index + 1, " of ", nv,
                            ", vt ", ix.texcoord_index + 1, " of ", nt, ", vn ", ix.normal_index + 1, " of ",
                            nn, ")");
        }
        const std::array<int, 3> key{ix.vertex_index, ix.texcoord_index, ix.normal_index};
        auto [it, inserted] = g.remap.try_emplace(key, static_cast<std::uint32_t>(g.mesh.positions_m.size()));
        if (inserted) {
          const std::size_t v = static_cast<std::size_t>(ix.vertex_index);
          g.mesh.positions_m.emplace_back(attrib.vertices[3 * v], attrib.vertices[3 * v + 1],
                                          attrib.vertices[3 * v + 2]);
          if (ix.normal_index >= 0) {
            const std::size_t n = static_cast<std::size_t>(ix.normal_index);
            g.mesh.normals.emplace_back(attrib.normals[3 * n], attrib.normals[3 * n + 1],
                                        attrib.normals[3 * n + 2]);
          } else {
            g.all_normals = false;
            g.mesh.normals.emplace_back(0.0f, 0.0f, 0.0f);
          }
          if (ix.texcoord_index >= 0) {
            const std::size_t t = static_cast<std::size_t>(ix.texcoord_index);
            // OBJ v runs up from the bottom of the image; ours runs down from the top.
            g.mesh.uvs.emplace_back(attrib.texcoords[2 * t], 1.0f - attrib.texcoords[2 * t + 1]);
            g.any_uv = true;
          } else {
            g.mesh.uvs.emplace_back(0.0f, 0.0f);
          }
        }
        corners.push_back(it->second);
      }
      // Fan triangulation (fine for the convex polygons modelling tools export).
      for (std::size_t k = 1; k + 1 < corners.size(); ++k) {
        g.mesh.indices.insert(g.mesh.indices.end(), {corners[0], corners[k], corners[k + 1]});
      }
      offset += fv;
    }
  }

  Model model;
  for (auto& [mat, g] : groups) {
    if (g.mesh.indices.empty()) continue;
    Mesh& mesh = g.mesh;
    if (!g.any_uv) mesh.uvs.clear();
    if (!g.all_normals) mesh.normals.clear();
    mesh.name = mat >= 0 && !materials[mat].name.empty() ? materials[mat].name : "default";
    if (mat >= 0) {
      const auto& m = materials[mat];
      mesh.base_color = Eigen::Vector3f(m.diffuse[0], m.diffuse[1], m.diffuse[2]);
      if (const auto f = finishes->find(m.name); f != finishes->end() && f->second.any())
        mesh.finish = f->second.finish(), mesh.finish_from_file = true;
      if (!m.diffuse_texname.empty()) {
        std::string name = m.diffuse_texname;
        std::replace(name.begin(), name.end(), '\\', '/');  // Windows exporters
        const fs::path tex_path = fs::path(name).is_absolute() ? fs::path(name) : dir / name;
        auto& tex = textures[tex_path.string()];
        if (!tex) {
          std::error_code ec;
          const cv::Mat img = fs::is_regular_file(tex_path, ec)
                                  ? cv::imread(tex_path.string(), cv::IMREAD_UNCHANGED)
                                  : cv::Mat();
          if (img.empty()) {
            return make_error(kWhere, path, ": material '", m.name, "': cannot read texture ",
                              tex_path.string());
          }
          tex = texture_from_mat(img);
          if (!tex)
            return make_error(kWhere, path, ": texture ", tex_path.string(), " has an unsupported format");
        }
        if (!mesh.uvs.empty()) mesh.texture = tex;
      }
    }
    fix_normals(mesh);
    model.meshes.push_back(std::move(mesh));
  }
  return model;
}

}  // namespace

// ----------------------------------------------------------------------------------------------

Expected<Model> load_model(const ModelSource& source) {
  namespace fs = std::filesystem;
  const std::string& path = source.path;
  if (path.empty()) {
    return make_error(kWhere, "empty path (the built-in models come from render/models.hpp)");
  }
  auto R = axes_rotation(source.axes, path);
  if (!R) return R.error();
  if (!(source.scale > 0.0) || !std::isfinite(source.scale)) {
    return make_error(kWhere, path, ": scale must be a positive finite number, got ", source.scale);
  }
  std::error_code ec;
  if (fs::is_directory(path, ec)) return make_error(kWhere, path, ": is a directory, expected a file");
  if (!fs::is_regular_file(path, ec)) return make_error(kWhere, path, ": file not found");

  const std::string ext = lower(fs::path(path).extension().string());
  Expected<Model> model = Error{};
  try {
    if (ext == ".gltf") {
      model = load_gltf(path, false);
    } else if (ext == ".glb") {
      model = load_gltf(path, true);
    } else if (ext == ".obj") {
      model = load_obj(path);
    } else {
      return make_error(kWhere, path, ": unknown extension '", ext, "' (expected .gltf, .glb or .obj)");
    }
  } catch (const std::exception& e) {  // e.g. bad_alloc on absurd sizes
    return make_error(kWhere, path, ": ", e.what());
  }
  if (!model) return model;
  if (model->triangle_count() == 0) return make_error(kWhere, path, ": no triangles");
  if (auto st = convert_to_frd(*model, *R, source.scale, path); !st) return st.error();
  return model;
}

}  // namespace augrig
