// Small OpenGL helpers shared by the augmenter and the scene renderer: shader programs, meshes on
// the GPU, textures and an offscreen framebuffer with colour + id attachments. All need a current
// context (render/gl_context.hpp).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <epoxy/gl.h>

#include "core/expected.hpp"
#include "render/mesh.hpp"

namespace augrig::gl {

// Compiles and links; errors carry the shader log and `name`.
Expected<GLuint> make_program(const std::string& name, const char* vertex_src, const char* fragment_src);

// The interleaved vertex every augrig shader reads: location 0 position, 1 normal, 2 uv.
struct Vertex {
  float pos[3];
  float normal[3];
  float uv[2];
};
// Declares Vertex's attributes for the bound vertex array and array buffer.
void set_vertex_attributes();

// An RGBA8 w x h texture, linear filtering, clamped to its edges, contents undefined; left bound.
GLuint make_rgba_texture(int w, int h);

// A mesh uploaded once: interleaved position, normal, uv, colour; 32-bit indices.
struct GpuMesh {
  GLuint vao = 0, vbo = 0, ebo = 0, texture = 0;
  GLsizei index_count = 0;
  bool has_texture = false;
  void draw() const;
  void destroy();
};
GpuMesh upload(const Mesh& mesh);

// Offscreen framebuffer, all RGBA8 but depth: colour0 shaded colour, colour1 packed ids, and
// colour2/colour3 a second id and colour target (the augmenter keeps the receiver's there so one
// clear per frame serves both passes), depth32F.
struct Framebuffer {
  GLuint fbo = 0, color = 0, ids = 0, ids2 = 0, color2 = 0, depth = 0;
  int width = 0, height = 0;
  Status create(int w, int h);
  void destroy();
};

// Reads an RGBA8 attachment's box [x0,x1)x[y0,y1) into `dst` (row stride dst_width*4 bytes, box placed
// at the same coordinates).
void read_rgba_box(GLenum attachment, int x0, int y0, int x1, int y1, std::uint8_t* dst, int dst_width);

// True when the context offers glClipControl (GL 4.5 or ARB_clip_control): reversed-Z in [0, 1].
bool has_clip_control();

// Throws nothing; returns "" or a description of pending GL errors.
std::string drain_errors();

}  // namespace augrig::gl
