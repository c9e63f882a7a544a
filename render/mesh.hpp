// Mesh and Model: triangle geometry in metres in an object frame (body FRD for aircraft, the boom
// frame for the boom), with normals, optional texture coordinates and an optional RGBA texture.
// Triangles wind counter-clockwise seen from outside (outward normals by the right-hand rule).
// Loaders for glTF 2.0 (.gltf/.glb, tinygltf) and Wavefront OBJ (tinyobjloader) convert the file's
// axes explicitly (ModelAxes in render/rig.hpp) and scale to metres; errors name file and what.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/expected.hpp"
#include "render/pbr.hpp"
#include "render/rig.hpp"

namespace augrig {

struct Texture {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgba;  // width*height*4, row 0 = v 0 (top of the image file)
};

struct Mesh {
  std::string name;
  std::vector<Eigen::Vector3f> positions_m;
  std::vector<Eigen::Vector3f> normals;  // unit, one per position
  std::vector<Eigen::Vector2f> uvs;      // empty, or one per position (u right, v down into the texture)
  std::vector<std::uint32_t> indices;    // 3 per triangle
  Eigen::Vector3f base_color{0.8f, 0.8f, 0.8f};  // linear 0..1, multiplied with the texture
  std::shared_ptr<const Texture> texture;        // may be null
  // Metallic and roughness (render/pbr.hpp): the file's (a glTF material's pbrMetallicRoughness,
  // an OBJ material's Pm / Pr / Ns), else the built-in boom's paint until the rig's
  // `boom.material` sets it (apply_boom_material(), render/models.hpp).
  SurfaceFinish finish = kPaintedBoom;
  bool finish_from_file = false;  // the model file gave it

  std::size_t triangle_count() const { return indices.size() / 3; }
  // Axis-aligned bounds of the positions; {min, max}.
  std::pair<Eigen::Vector3f, Eigen::Vector3f> bounds() const;
};

// A model is a list of meshes that move together.
struct Model {
  std::vector<Mesh> meshes;
  std::size_t triangle_count() const;
  std::pair<Eigen::Vector3f, Eigen::Vector3f> bounds() const;
};

// Recomputes smooth vertex normals from the triangles (area weighted).
void compute_normals(Mesh& mesh);

// Loads .gltf/.glb/.obj by extension, converting axes and scale; all primitives/shapes are kept
// (node transforms applied for glTF), textures from baseColorTexture / map_Kd when present,
// metallic and roughness from pbrMetallicRoughness (glTF's defaults, 1 and 1, where a material
// leaves them out) or from an OBJ material's Pm, Pr and Ns (roughness (2 / (Ns + 2))^(1/4));
// either out of [0, 1] (Ns below 0) is an Error naming the file and the material.
Expected<Model> load_model(const ModelSource& source);

}  // namespace augrig
