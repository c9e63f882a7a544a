#include "render/gl_util.hpp"

#include <cstddef>

namespace augrig::gl {

namespace {
Expected<GLuint> compile(const std::string& name, GLenum type, const char* src) {
  GLuint s = glCreateShader(type);
  glShaderSource(s, 1, &src, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[4096] = {};
    glGetShaderInfoLog(s, sizeof(log), nullptr, log);
    glDeleteShader(s);
    return make_error("gl::make_program(): ", name, (type == GL_VERTEX_SHADER ? " vertex" : " fragment"),
                      " shader: ", log);
  }
  return s;
}

}  // namespace

void set_vertex_attributes() {
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, sizeof(Vertex),
                        reinterpret_cast<void*>(offsetof(Vertex, pos)));
  glEnableVertexAttribArray(1);
  glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, sizeof(Vertex),
                        reinterpret_cast<void*>(offsetof(Vertex, normal)));
  glEnableVertexAttribArray(2);
  glVertexAttribPointer(2, 2, GL_FLOAT, GL_FALSE, sizeof(Vertex),
                        reinterpret_cast<void*>(offsetof(Vertex, uv)));
}

GLuint make_rgba_texture(int w, int h) {
  GLuint t = 0;
  glGenTextures(1, &t);
  glBindTexture(GL_TEXTURE_2D, t);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, w, h, 0, GL_RGBA, GL_UNSIGNED_BYTE, nullptr);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  return t;
}

Expected<GLuint> make_program(const std::string& name, const char* vertex_src, const char* fragment_src) {
  auto vs = compile(name, GL_VERTEX_SHADER, vertex_src);
  if (!vs) return vs.error();
  auto fs = compile(name, GL_FRAGMENT_SHADER, fragment_src);
  if (!fs) {
    glDeleteShader(*vs);
    return fs.error();
  }
  GLuint p = glCreateProgram();
  glAttachShader(p, *vs);
  glAttachShader(p, *fs);
  glLinkProgram(p);
  glDeleteShader(*vs);
  glDeleteShader(*fs);
  GLint ok = 0;
  glGetProgramiv(p, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[4096] = {};
    glGetProgramInfoLog(p, sizeof(log), nullptr, log);
    glDeleteProgram(p);
    return make_error("gl::make_program(): ", name, " link: ", log);
  }
  return p;
}

GpuMesh upload(const Mesh& mesh) {
  GpuMesh g;
  std::vector<Vertex> verts(mesh.positions_m.size());
  for (std::size_t i = 0; i < verts.size(); ++i) {
    const auto& p = mesh.positions_m[i];
    const Eigen::Vector3f n = i < mesh.normals.size() ? mesh.normals[i] : Eigen::Vector3f::UnitZ();
    const Eigen::Vector2f t = i < mesh.uvs.size() ? mesh.uvs[i] : Eigen::Vector2f::Zero();
    verts[i] = {{p.x(), p.y(), p.z()}, {n.x(), n.y(), n.z()}, {t.x(), t.y()}};
  }
  glGenVertexArrays(1, &g.vao);
  glBindVertexArray(g.vao);
  glGenBuffers(1, &g.vbo);
  glBindBuffer(GL_ARRAY_BUFFER, g.vbo);
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(verts.size() * sizeof(Vertex)), verts.data(),
               GL_STATIC_DRAW);
  glGenBuffers(1, &g.ebo);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, g.ebo);
  glBufferData(GL_ELEMENT_ARRAY_BUFFER, static_cast<GLsizeiptr>(mesh.indices.size() * sizeof(std::uint32_t)),
               mesh.indices.data(), GL_STATIC_DRAW);
  set_vertex_attributes();
  glBindVertexArray(0);
  g.index_count = static_cast<GLsizei>(mesh.indices.size());
  if (mesh.texture && mesh.texture->width > 0 && !mesh.uvs.empty()) {
    glGenTextures(1, &g.texture);
    glBindTexture(GL_TEXTURE_2D, g.texture);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, mesh.texture->width, mesh.texture->height, 0, GL_RGBA,
                 GL_UNSIGNED_BYTE, mesh.texture->rgba.data());
    glGenerateMipmap(GL_TEXTURE_2D);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_REPEAT);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_REPEAT);
    g.has_texture = true;
  }
  return g;
}

void GpuMesh::draw() const {
  glBindVertexArray(vao);
  glDrawElements(GL_TRIANGLES, index_count, GL_UNSIGNED_INT, nullptr);
}

void GpuMesh::destroy() {
  if (texture) glDeleteTextures(1, &texture);
  if (ebo) glDeleteBuffers(1, &ebo);
  if (vbo) glDeleteBuffers(1, &vbo);
  if (vao) glDeleteVertexArrays(1, &vao);
  *this = {};
}

Status Framebuffer::create(int w, int h) {
  width = w, height = h;
  glGenFramebuffers(1, &fbo);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  auto make_rb = [&](GLenum fmt, GLenum attachment) {
    GLuint rb = 0;
    glGenRenderbuffers(1, &rb);
    glBindRenderbuffer(GL_RENDERBUFFER, rb);
    glRenderbufferStorage(GL_RENDERBUFFER, fmt, w, h);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, attachment, GL_RENDERBUFFER, rb);
    return rb;
  };
  color = make_rb(GL_RGBA8, GL_COLOR_ATTACHMENT0);
  ids = make_rb(GL_RGBA8, GL_COLOR_ATTACHMENT1);
  ids2 = make_rb(GL_RGBA8, GL_COLOR_ATTACHMENT2);
  color2 = make_rb(GL_RGBA8, GL_COLOR_ATTACHMENT3);
  depth = make_rb(GL_DEPTH_COMPONENT32F, GL_DEPTH_ATTACHMENT);
  const GLenum bufs[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
  glDrawBuffers(2, bufs);
  const GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE)
    return make_error("gl::Framebuffer::create(): ", w, "x", h, " framebuffer incomplete (status 0x",
                      static_cast<unsigned>(status), ")");
  return {};
}

void Framebuffer::destroy() {
  const GLuint rbs[5] = {color, ids, ids2, color2, depth};
  glDeleteRenderbuffers(5, rbs);
  if (fbo) glDeleteFramebuffers(1, &fbo);
  *this = {};
}

void read_rgba_box(GLenum attachment, int x0, int y0, int x1, int y1, std::uint8_t* dst, int dst_width) {
  if (x1 <= x0 || y1 <= y0) return;
  glReadBuffer(attachment);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glPixelStorei(GL_PACK_ROW_LENGTH, dst_width);
  glReadPixels(x0, y0, x1 - x0, y1 - y0, GL_RGBA, GL_UNSIGNED_BYTE,
               dst + (static_cast<std::size_t>(y0) * dst_width + x0) * 4);
  glPixelStorei(GL_PACK_ROW_LENGTH, 0);
}

bool has_clip_control() {
  return epoxy_gl_version() >= 45 || epoxy_has_gl_extension("GL_ARB_clip_control");
}

std::string drain_errors() {
  std::string out;
  for (GLenum e = glGetError(); e != GL_NO_ERROR; e = glGetError()) out += " 0x" + std::to_string(e);
  return out;
}

}  // namespace augrig::gl
