// Built-in procedural models (render/models.hpp is the spec; docs/MODELS.md gives dimensions and sources).
//
// Every part is a closed shell built by lofting cross-sections (circles, ellipses, airfoils) along a
// path and capping the ends. Each shell is oriented outward by its signed volume, so the winding
// never depends on which way a section happens to be parametrised. Normals are smooth within a
// "smoothing group" and creased between groups (vertices are duplicated at creases).
#include "render/models.hpp"

#include <cmath>
#include <functional>
#include <map>
#include <string>
#include <tuple>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "core/conventions.hpp"

namespace augrig {
namespace {

using Eigen::Vector2f;
using Eigen::Vector3f;

// ----------------------------------------------------------------------------------------------
// Shell building

struct Builder {
  Mesh mesh;
  std::vector<std::int64_t> group;  // smoothing group of each vertex
  std::int64_t next_group = 1;

  std::uint32_t vertex(const Vector3f& p, const Vector2f& uv, std::int64_t g) {
    mesh.positions_m.push_back(p);
    mesh.uvs.push_back(uv);
    group.push_back(g);
    return static_cast<std::uint32_t>(mesh.positions_m.size() - 1);
  }
  // Skips degenerate triangles (e.g. the zero-area half of a quad touching a pole).
  void triangle(std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    const auto& P = mesh.positions_m;
    if ((P[b] - P[a]).cross(P[c] - P[a]).squaredNorm() < 1e-14f) return;
    mesh.indices.insert(mesh.indices.end(), {a, b, c});
  }

  // Normals: area-weighted average of the face normals around each (group, position), so vertices
  // duplicated only for a texture seam or a pole still share one smooth normal.
  Mesh finish(std::string name, const Vector3f& color, std::shared_ptr<const Texture> texture) {
    using Key = std::tuple<std::int64_t, float, float, float>;
    auto key = [&](std::uint32_t i) {
      const auto& p = mesh.positions_m[i];
      return Key{group[i], p.x(), p.y(), p.z()};
    };
    std::map<Key, Vector3f> acc;
    for (std::size_t t = 0; t < mesh.indices.size(); t += 3) {
      const std::uint32_t a = mesh.indices[t], b = mesh.indices[t + 1], c = mesh.indices[t + 2];
      const auto& P = mesh.positions_m;
      const Vector3f fn = (P[b] - P[a]).cross(P[c] - P[a]);
      for (std::uint32_t v : {a, b, c}) {
        auto [it, inserted] = acc.try_emplace(key(v), Vector3f::Zero());
        it->second += fn;
      }
    }
    mesh.normals.resize(mesh.positions_m.size());
    for (std::size_t i = 0; i < mesh.positions_m.size(); ++i) {
      const auto it = acc.find(key(static_cast<std::uint32_t>(i)));
      const Vector3f n = it == acc.end() ? Vector3f::Zero() : it->second;
      mesh.normals[i] = n.norm() > 0 ? Vector3f(n.normalized()) : Vector3f(0, 0, -1);
    }
    mesh.name = std::move(name);
    mesh.base_color = color;
    mesh.texture = std::move(texture);
    if (!mesh.texture) mesh.uvs.clear();
    return std::move(mesh);
  }
};

using Section = std::vector<Vector3f>;

struct Loft {
  std::vector<Section> sections;     // each with the same number of points N (a pole: N equal points)
  std::vector<bool> ring_crease;     // N flags: sharp edge along the loft at ring point j (empty: none)
  std::vector<bool> section_crease;  // per section: sharp edge around the ring (empty: none)
  // uv of ring point j (0..N, N repeats 0 on the far side of the texture seam) of section i.
  std::function<Vector2f(int i, int j)> uv = [](int, int) { return Vector2f::Zero(); };
};

bool is_pole(const Section& s) {
  for (const auto& p : s)
    if ((p - s.front()).squaredNorm() > 1e-14f) return false;
  return true;
}

// Emits the loft as one closed shell: side quads between consecutive sections, flat caps at ends
// that are not poles. Then flips the shell if its signed volume is negative (inside out).
void loft(Builder& b, const Loft& L) {
  const int S = static_cast<int>(L.sections.size());
  const int N = static_cast<int>(L.sections.front().size());
  const std::size_t first_index = b.mesh.indices.size();
  const std::int64_t side_group = b.next_group++;

  // Span ids: faces in the same span share smooth normals; a crease starts a new span.
  std::vector<int> ring_span(N, 0), sec_span(std::max(S - 1, 1), 0);
  for (int k = 1; k < N; ++k) ring_span[k] = ring_span[k - 1] + (!L.ring_crease.empty() && L.ring_crease[k]);
  if (!L.ring_crease.empty() && !L.ring_crease[0]) {
    // No crease at point 0: the span wrapping round the texture seam joins the first one.
    int last = -1;
    for (int k = 1; k < N; ++k)
      if (L.ring_crease[k]) last = k;
    if (last > 0)
      for (int k = last; k < N; ++k) ring_span[k] = 0;
  }
  for (int q = 1; q < S - 1; ++q)
    sec_span[q] = sec_span[q - 1] + (!L.section_crease.empty() && L.section_crease[q]);

  std::map<std::tuple<int, int, int, int>, std::uint32_t> made;
  // Vertex of ring point j of section i as used by the quad in row q, column k.
  auto side_vertex = [&](int i, int j, int q, int k) {
    const auto key = std::make_tuple(i, j, sec_span[q], ring_span[k]);
    if (auto it = made.find(key); it != made.end()) return it->second;
    const std::int64_t g = (side_group << 32) | (static_cast<std::int64_t>(sec_span[q]) << 16) | ring_span[k];
    const std::uint32_t v = b.vertex(L.sections[i][j % N], L.uv(i, j), g);
    made.emplace(key, v);
    return v;
  };
  for (int q = 0; q + 1 < S; ++q) {
    for (int k = 0; k < N; ++k) {
      const std::uint32_t a = side_vertex(q, k, q, k), bb = side_vertex(q, k + 1, q, k);
      const std::uint32_t c = side_vertex(q + 1, k + 1, q, k), d = side_vertex(q + 1, k, q, k);
      b.triangle(a, bb, d);
      b.triangle(bb, c, d);
    }
  }
  // Caps: a fan around the centroid, winding chosen to match the side quads' edges.
  auto cap = [&](int i, bool at_end) {
    const Section& s = L.sections[i];
    if (is_pole(s)) return;
    const std::int64_t g = b.next_group++ << 32;
    Vector3f centre = Vector3f::Zero();
    Vector2f uv_centre = Vector2f::Zero();
    std::vector<std::uint32_t> ring;
    for (int j = 0; j < N; ++j) {
      centre += s[j];
      uv_centre += L.uv(i, j);
      ring.push_back(b.vertex(s[j], L.uv(i, j), g));
    }
    const std::uint32_t c = b.vertex(centre / N, uv_centre / N, g);
    for (int j = 0; j < N; ++j) {
      const std::uint32_t p0 = ring[j], p1 = ring[(j + 1) % N];
      if (at_end) {
        b.triangle(c, p0, p1);
      } else {
        b.triangle(c, p1, p0);
      }
    }
  };
  cap(0, false);
  cap(S - 1, true);

  // Orientation: the signed volume of a closed shell is positive when its faces point outward.
  const auto& P = b.mesh.positions_m;
  auto& I = b.mesh.indices;
  Vector3f ref = P[I[first_index]];
  double volume = 0;
  for (std::size_t t = first_index; t < I.size(); t += 3) {
    const Eigen::Vector3d p0 = (P[I[t]] - ref).cast<double>(), p1 = (P[I[t + 1]] - ref).cast<double>(),
                          p2 = (P[I[t + 2]] - ref).cast<double>();
    volume += p0.dot(p1.cross(p2)) / 6.0;
  }
  if (volume < 0) {
    for (std::size_t t = first_index; t < I.size(); t += 3) std::swap(I[t + 1], I[t + 2]);
  }
}

// Ellipse section around an axis parallel to x: centre (x, yc, zc), half-width a (y), half-height b
// (z). Point j is at angle 2*pi*j/n from the bottom (+z) through the right side (+y) and the top.
Section ellipse_x(double x, double yc, double zc, double a, double b, int n) {
  Section s(n);
  for (int j = 0; j < n; ++j) {
    const double th = 2.0 * kPi * j / n;
    // Exact zeros at the bottom and top keep the top-centre line (receptacle, tests) exactly at y = yc.
    const double sy = (2 * j == n || j == 0) ? 0.0 : std::sin(th);
    s[j] = Eigen::Vector3d(x, yc + a * sy, zc + b * std::cos(th)).cast<float>();
  }
  return s;
}

// NACA 4-digit symmetric half-thickness at chord fraction f for thickness ratio t (open 0.2% TE).
double naca_half_thickness(double f, double t) {
  return 5.0 * t *
         (0.2969 * std::sqrt(f) - 0.1260 * f - 0.3516 * f * f + 0.2843 * f * f * f - 0.1015 * f * f * f * f);
}

// Airfoil outline as (chord fraction, thickness offset) pairs: trailing edge upper, forward along the
// upper surface to the leading edge, back along the lower surface to the trailing edge lower.
std::vector<std::pair<double, double>> naca_outline(double t) {
  static const double kF[] = {1.0, 0.7, 0.45, 0.25, 0.1, 0.025};
  std::vector<std::pair<double, double>> out;
  for (double f : kF) out.emplace_back(f, naca_half_thickness(f, t));
  out.emplace_back(0.0, 0.0);
  for (int i = 5; i >= 0; --i) out.emplace_back(kF[i], -naca_half_thickness(kF[i], t));
  return out;  // 13 points; creases at 0 and 12 (the blunt trailing edge)
}

std::vector<bool> airfoil_creases(std::size_t n) {
  std::vector<bool> c(n, false);
  c[0] = c[n - 1] = true;
  return c;
}

// ----------------------------------------------------------------------------------------------
// Boom

// Light grey tube paint with dark bands; u = (x - x0) / (x1 - x0) along the part.
std::shared_ptr<const Texture> band_texture(double x0, double x1,
                                            const std::vector<std::pair<double, double>>& dark) {
  auto tex = std::make_shared<Texture>();
  tex->width = 512;
  tex->height = 4;
  tex->rgba.resize(static_cast<std::size_t>(tex->width) * tex->height * 4);
  for (int c = 0; c < tex->width; ++c) {
    const double x = x0 + (c + 0.5) / tex->width * (x1 - x0);
    bool is_dark = false;
    for (const auto& [a, b] : dark) is_dark = is_dark || (x >= a && x < b);
    const std::uint8_t rgb[3] = {static_cast<std::uint8_t>(is_dark ? 35 : 222),
                                 static_cast<std::uint8_t>(is_dark ? 35 : 224),
                                 static_cast<std::uint8_t>(is_dark ? 38 : 228)};
    for (int r = 0; r < tex->height; ++r) {
      std::uint8_t* p = tex->rgba.data() + (static_cast<std::size_t>(r) * tex->width + c) * 4;
      p[0] = rgb[0];
      p[1] = rgb[1];
      p[2] = rgb[2];
      p[3] = 255;
    }
  }
  return tex;
}

constexpr int kBoomSegments = 24;

Section circle_x(double x, double r) {
  return ellipse_x(x, 0.0, 0.0, r, r, kBoomSegments);
}

// A tube of radius r from x0 to x1 in equal sections no longer than kMaxTubeSection_m, u running
// 0..1 along it: long side triangles would give the renderer's per-chunk screen boxes the whole
// tube's extent (a long diagonal covers a small part of its box).
constexpr double kMaxTubeSection_m = 1.5;
std::vector<std::pair<double, double>> tube_profile(double x0, double x1, double r) {
  const int n = std::max(1, static_cast<int>(std::ceil((x1 - x0) / kMaxTubeSection_m)));
  std::vector<std::pair<double, double>> profile;
  for (int i = 0; i <= n; ++i) profile.emplace_back(x0 + (x1 - x0) * i / n, r);
  return profile;
}

// Surface of revolution about the boom x axis through (x, r) profile points.
Loft lathe(const std::vector<std::pair<double, double>>& profile, std::function<Vector2f(int i, int j)> uv) {
  Loft L;
  for (const auto& [x, r] : profile) L.sections.push_back(circle_x(x, r));
  L.uv = std::move(uv);
  return L;
}

// One ruddevator panel: a thin tapered slab rising from the tube at `side` = +1 (boom +y) or -1.
void ruddevator(Builder& b, const BoomDimensions& d, double side) {
  const double dih = deg_to_rad(d.ruddevator_dihedral_deg);
  // Span direction: outward and up (boom -z is up when the boom is level).
  const Eigen::Vector3d span(0.0, side * std::cos(dih), -std::sin(dih));
  const Eigen::Vector3d thick(0.0, std::sin(dih) * side, std::cos(dih));  // normal to the panel
  const double r_tube = d.fixed_tube_diameter_m / 2;
  const double r_root = r_tube - 0.05;  // root buried 5 cm in the tube: no gap at any angle
  const double r_tip = r_tube + d.ruddevator_span_m;
  const double tc = d.ruddevator_thickness_m / d.ruddevator_chord_m;
  // Tip leading edge swept back so the trailing edge stays roughly straight.
  const double tip_le =
      d.ruddevator_station_m + 0.5 * (d.ruddevator_chord_m - d.ruddevator_tip_chord_m) + 0.2;
  static const double kF[] = {0.0, 0.15, 0.4, 0.75, 1.0, 0.75, 0.4, 0.15};
  static const double kH[] = {0.0, 0.8, 1.0, 0.6, 0.0, -0.6, -1.0, -0.8};
  Loft L;
  for (int s = 0; s < 2; ++s) {
    const double r = s == 0 ? r_root : r_tip;
    const double le = s == 0 ? d.ruddevator_station_m : tip_le;
    const double chord = s == 0 ? d.ruddevator_chord_m : d.ruddevator_tip_chord_m;
    Section sec;
    for (int k = 0; k < 8; ++k) {
      const Eigen::Vector3d p =
          Eigen::Vector3d(le + kF[k] * chord, 0, 0) + r * span + 0.5 * tc * chord * kH[k] * thick;
      sec.push_back(p.cast<float>());
    }
    L.sections.push_back(sec);
  }
  L.ring_crease.assign(8, true);  // flat-shaded slab
  loft(b, L);
}

}  // namespace

void apply_boom_material(BoomModel& boom, const std::optional<SurfaceFinish>& material) {
  if (!material) return;
  for (Model* part : {&boom.fixed, &boom.telescope})
    for (Mesh& m : part->meshes)
      if (!m.finish_from_file) m.finish = *material;
}

BoomModel make_builtin_boom(const BoomDimensions& d) {
  BoomModel boom;
  boom.dims = d;
  const double r_tube = d.fixed_tube_diameter_m / 2;
  const double r_fair = d.fairing_diameter_m / 2;
  const double N = kBoomSegments;

  // Root fairing: a short streamlined body of revolution around the pivot, tapering into the tube.
  {
    Builder b;
    const std::vector<std::pair<double, double>> prof = {
        {-0.30, 0.0},   {-0.26, 0.43 * r_fair}, {-0.17, 0.77 * r_fair}, {-0.04, 0.97 * r_fair},
        {0.12, r_fair}, {0.40, 0.91 * r_fair},  {0.75, 0.77 * r_fair},  {1.10, r_tube + 0.005}};
    loft(b, lathe(prof, [](int, int) { return Vector2f::Zero(); }));
    boom.fixed.meshes.push_back(b.finish("fairing", Vector3f(0.80f, 0.81f, 0.83f), nullptr));
  }
  // Outer tube with a couple of dark bands near its aft end.
  {
    Builder b;
    const double x1 = d.fixed_tube_length_m;
    auto tex = band_texture(0.0, x1, {{x1 - 0.55, x1 - 0.45}, {x1 - 0.30, x1 - 0.20}});
    const auto profile = tube_profile(0.0, x1, r_tube);
    Loft L = lathe(profile, nullptr);
    const double sections = static_cast<double>(profile.size() - 1);
    L.uv = [N, sections](int i, int j) {
      return Vector2f(static_cast<float>(i / sections), static_cast<float>(j / N));
    };
    loft(b, L);
    boom.fixed.meshes.push_back(b.finish("outer_tube", Vector3f(1, 1, 1), tex));
  }
  // Ruddevators in a V.
  {
    Builder b;
    ruddevator(b, d, +1.0);
    ruddevator(b, d, -1.0);
    boom.fixed.meshes.push_back(b.finish("ruddevators", Vector3f(0.82f, 0.83f, 0.85f), nullptr));
  }

  // Telescope (at extension 0): its aft end sticks out `telescope_stick_out_m` beyond the outer tube.
  const double t_end = d.fixed_tube_length_m + d.telescope_stick_out_m;
  const double t_start = t_end - d.telescope_length_m;
  {
    Builder b;
    const double r = d.telescope_diameter_m / 2;
    // Extension index marks (visible once the telescope runs out past them) and a band by the nozzle.
    auto tex = band_texture(t_start, t_end,
                            {{t_end - 5.6, t_end - 5.5},
                             {t_end - 3.6, t_end - 3.5},
                             {t_end - 1.6, t_end - 1.5},
                             {t_end - 0.45, t_end - 0.30}});
    const auto profile = tube_profile(t_start, t_end, r);
    Loft L = lathe(profile, nullptr);
    const double sections = static_cast<double>(profile.size() - 1);
    L.uv = [N, sections](int i, int j) {
      return Vector2f(static_cast<float>(i / sections), static_cast<float>(j / N));
    };
    loft(b, L);
    boom.telescope.meshes.push_back(b.finish("inner_tube", Vector3f(1, 1, 1), tex));
  }
  // Nozzle: ball joint, neck and a conical nozzle ending exactly at nozzle_tip_m(0).
  {
    Builder b;
    const double k = d.nozzle_length_m / 0.5;  // profile designed for a 0.5 m nozzle
    const double rt = d.telescope_diameter_m / 2;
    const std::vector<std::pair<double, double>> prof = {
        {t_end - 0.05 * k, 0.80 * rt},         {t_end, 0.96 * rt},
        {t_end + 0.04 * k, 1.20 * rt},         {t_end + 0.09 * k, 1.32 * rt},
        {t_end + 0.14 * k, 1.20 * rt},         {t_end + 0.19 * k, 0.92 * rt},
        {t_end + 0.25 * k, 0.88 * rt},         {t_end + 0.42 * k, 0.68 * rt},
        {t_end + d.nozzle_length_m, 0.52 * rt}};
    loft(b, lathe(prof, [](int, int) { return Vector2f::Zero(); }));
    boom.telescope.meshes.push_back(b.finish("nozzle", Vector3f(0.28f, 0.28f, 0.30f), nullptr));
  }
  return boom;
}

// ----------------------------------------------------------------------------------------------
// Receiver

namespace {

// Receiver layout (body FRD, metres; origin near the CG, roughly at the wing root quarter chord).
constexpr double kNoseX = 5.15;
constexpr double kTailX = -8.15;
constexpr double kReceptacleX = 4.0;
constexpr int kFuselageSegments = 40;

struct FuselageStation {
  double x, zc, a, b;  // station, centre height, half-width, half-height
};
// Nose pole to tail pole; cabin ~1.48 m wide and ~1.66 m high (King Air 200 class).
const FuselageStation kFuselage[] = {
    {5.15, -0.20, 0.00, 0.00},  {5.10, -0.20, 0.10, 0.09},  {5.00, -0.21, 0.19, 0.17},
    {4.82, -0.23, 0.30, 0.28},  {4.55, -0.26, 0.42, 0.41},  {4.30, -0.28, 0.50, 0.51},
    {4.00, -0.30, 0.57, 0.60},  {3.60, -0.32, 0.63, 0.69},  {3.20, -0.34, 0.68, 0.77},
    {2.70, -0.35, 0.72, 0.82},  {1.80, -0.35, 0.74, 0.83},  {-2.80, -0.35, 0.74, 0.83},
    {-3.80, -0.37, 0.70, 0.79}, {-4.80, -0.41, 0.61, 0.68}, {-5.80, -0.47, 0.49, 0.54},
    {-6.70, -0.54, 0.36, 0.39}, {-7.40, -0.60, 0.24, 0.26}, {-7.90, -0.65, 0.12, 0.13},
    {-8.15, -0.68, 0.00, 0.00}};

// Wing: straight taper, 5 deg dihedral, low wing.
constexpr double kWingRootY = 0.30, kWingTipY = 8.30;
constexpr double kWingRootZ = 0.30;
constexpr double kWingDihedralDeg = 5.0;
constexpr double kWingRootLe = 1.00, kWingRootChord = 2.25, kWingRootTc = 0.15;
constexpr double kWingTipLe = 0.55, kWingTipChord = 1.05, kWingTipTc = 0.12;
constexpr double kNacelleY = 2.55;

// Texture atlas (1024 x 512): fuselage rows 0-255 (cylindrical), wing rows 256-383 cols 0-767,
// nacelles cols 768-959 and spinners cols 960-1023 of rows 256-383, tailplane rows 384-447 cols 0-511,
// fin rows 384-511 cols 512-1023 (planar).
constexpr int kTexW = 1024, kTexH = 512;
float fus_u(double x) {
  return static_cast<float>((kNoseX - x) / (kNoseX - kTailX));
}
float fus_v(double theta) {
  return static_cast<float>(0.5 * theta / (2 * kPi));
}
float wing_u(double y) {
  return static_cast<float>(0.75 * (y + 8.4) / 16.8);
}
float wing_v(double x) {
  return static_cast<float>(0.5 + 0.25 * (1.1 - x) / 2.45);
}
float nac_u(double x) {
  return static_cast<float>(0.75 + 0.1875 * (2.95 - x) / 5.2);
}
float nac_v(double theta) {
  return static_cast<float>(0.5 + 0.25 * theta / (2 * kPi));
}
float ht_u(double y) {
  return static_cast<float>(0.5 * (y + 2.9) / 5.8);
}
float ht_v(double x) {
  return static_cast<float>(0.75 + 0.125 * (-6.35 - x) / 1.6);
}
float fin_u(double x) {
  return static_cast<float>(0.5 + 0.5 * (-4.6 - x) / 3.4);
}
float fin_v(double z) {
  return static_cast<float>(0.75 + 0.25 * (z + 3.1) / 2.5);
}

double wing_z(double y) {
  return kWingRootZ - (std::abs(y) - kWingRootY) * std::tan(deg_to_rad(kWingDihedralDeg));
}
double wing_le(double y) {
  const double s = (std::abs(y) - kWingRootY) / (kWingTipY - kWingRootY);
  return kWingRootLe + s * (kWingTipLe - kWingRootLe);
}
double wing_chord(double y) {
  const double s = (std::abs(y) - kWingRootY) / (kWingTipY - kWingRootY);
  return kWingRootChord + s * (kWingTipChord - kWingRootChord);
}

// Texture pixel helpers (column from u, row from v).
int px(double u) {
  return static_cast<int>(std::lround(u * kTexW));
}
int py(double v) {
  return static_cast<int>(std::lround(v * kTexH));
}
// Fuselage row of the angle whose cosine is c, on the right (+y, theta < pi) or left side.
int fus_row(double c, bool right) {
  const double th = std::acos(std::clamp(c, -1.0, 1.0));
  return py(fus_v(right ? th : 2 * kPi - th));
}

// Draws text so it reads correctly on the fuselage side (the right side is mapped rotated 180 deg).
void fuselage_text(cv::Mat& img, const std::string& text, double x_fwd, double x_aft, double c_top,
                   double c_bot, bool right, const cv::Scalar& colour) {
  const int c0 = px(fus_u(x_fwd)), c1 = px(fus_u(x_aft));
  int r0 = fus_row(c_top, right), r1 = fus_row(c_bot, right);
  if (r0 > r1) std::swap(r0, r1);
  const cv::Rect box(c0, r0, c1 - c0, r1 - r0);
  cv::Mat patch(box.size(), img.type(), cv::Scalar::all(0));
  int base = 0;
  const cv::Size ts = cv::getTextSize(text, cv::FONT_HERSHEY_DUPLEX, 1.0, 2, &base);
  const double scale = std::min(0.9 * box.width / ts.width, 0.85 * box.height / ts.height);
  const cv::Size s2 = cv::getTextSize(text, cv::FONT_HERSHEY_DUPLEX, scale, 2, &base);
  cv::Mat mask(box.size(), CV_8U, cv::Scalar(0));
  cv::putText(mask, text, cv::Point((box.width - s2.width) / 2, (box.height + s2.height) / 2),
              cv::FONT_HERSHEY_DUPLEX, scale, cv::Scalar(255), 2, cv::LINE_AA);
  if (right) cv::rotate(mask, mask, cv::ROTATE_180);
  patch.setTo(colour);
  patch.copyTo(img(box), mask);
}

std::shared_ptr<const Texture> livery_texture() {
  cv::Mat img(kTexH, kTexW, CV_8UC3, cv::Scalar(244, 244, 242));  // BGR
  const cv::Scalar blue(140, 55, 18), red(40, 30, 185), dark(48, 44, 42), panel(190, 190, 192),
      grey(208, 206, 204);
  const cv::Scalar yellow(40, 200, 235);

  // --- Fuselage (rows 0-255): belly, cheat lines, windows, windscreen, door, receptacle, registration.
  cv::rectangle(img, cv::Rect(0, 0, kTexW, fus_row(0.78, true)), grey, cv::FILLED);
  cv::rectangle(img, cv::Rect(0, fus_row(0.78, false), kTexW, 256 - fus_row(0.78, false)), grey, cv::FILLED);
  for (bool right : {true, false}) {
    auto band = [&](double c_hi, double c_lo, double x0, double x1, const cv::Scalar& col) {
      int r0 = fus_row(c_hi, right), r1 = fus_row(c_lo, right);
      if (r0 > r1) std::swap(r0, r1);
      cv::rectangle(img, cv::Rect(px(fus_u(x0)), r0, px(fus_u(x1)) - px(fus_u(x0)), std::max(r1 - r0, 1)),
                    col, cv::FILLED);
    };
    band(0.12, -0.06, 4.3, -7.6, blue);    // main cheat line
    band(0.22, 0.17, 4.1, -7.2, red);      // pin stripe below it
    band(-0.30, -0.36, -3.0, -6.9, blue);  // upper aft stripe
    // Cabin windows and cockpit side windows.
    for (double x : {1.6, 0.85, 0.1, -0.65, -1.4, -2.15}) band(-0.15, -0.55, x + 0.16, x - 0.16, dark);
    band(-0.25, -0.70, 3.15, 2.55, dark);
    // Registration aft of the windows, above the cheat line.
    fuselage_text(img, "N350AG", -3.1, -5.6, -0.72, -0.12, right, blue);
  }
  // Windscreen over the top (rows either side of the top line), door outline on the left.
  cv::rectangle(img,
                cv::Rect(px(fus_u(3.55)), fus_row(-0.78, true), px(fus_u(3.15)) - px(fus_u(3.55)),
                         fus_row(-0.78, false) - fus_row(-0.78, true)),
                dark, cv::FILLED);
  cv::rectangle(img,
                cv::Rect(px(fus_u(-2.65)), fus_row(-0.62, false), px(fus_u(-3.35)) - px(fus_u(-2.65)),
                         fus_row(0.55, false) - fus_row(-0.62, false)),
                dark, 1);
  // Receptacle marking on top of the nose: dark square with yellow guide lines running aft.
  {
    const int top = py(fus_v(kPi)), c = px(fus_u(kReceptacleX));
    cv::rectangle(img, cv::Rect(c - 10, top - 8, 20, 16), dark, cv::FILLED);
    cv::line(img, cv::Point(c + 10, top - 5), cv::Point(c + 38, top - 3), yellow, 2);
    cv::line(img, cv::Point(c + 10, top + 5), cv::Point(c + 38, top + 3), yellow, 2);
  }
  // Panel lines: frames (constant x) and stringers (constant angle).
  for (double x : {4.6, 4.2, 3.0, 2.2, 1.0, -0.3, -1.6, -2.5, -4.5, -6.0, -7.2}) {
    cv::line(img, cv::Point(px(fus_u(x)), 0), cv::Point(px(fus_u(x)), 255), panel, 1);
  }
  for (int r : {32, 96, 160, 224})
    cv::line(img, cv::Point(px(fus_u(2.6)), r), cv::Point(px(fus_u(-7.8)), r), panel, 1);

  // --- Wings (rows 256-383, cols 0-767): leading-edge boots, walkways, flap lines, red tips.
  for (double side : {1.0, -1.0}) {
    auto pt = [&](double y, double x) { return cv::Point(px(wing_u(side * y)), py(wing_v(x))); };
    auto chord_pt = [&](double y, double f) { return pt(y, wing_le(y) - f * wing_chord(y)); };
    const std::vector<cv::Point> boot = {chord_pt(0.75, 0.0), chord_pt(kWingTipY - 0.4, 0.0),
                                         chord_pt(kWingTipY - 0.4, 0.1), chord_pt(0.75, 0.1)};
    cv::fillConvexPoly(img, boot, dark);
    const std::vector<cv::Point> walk = {chord_pt(0.75, 0.25), chord_pt(1.3, 0.25), chord_pt(1.3, 0.7),
                                         chord_pt(0.75, 0.7)};
    cv::fillConvexPoly(img, walk, cv::Scalar(110, 108, 106));
    const std::vector<cv::Point> tip = {chord_pt(kWingTipY - 0.35, -0.05), chord_pt(kWingTipY + 0.1, -0.05),
                                        chord_pt(kWingTipY + 0.1, 1.05), chord_pt(kWingTipY - 0.35, 1.05)};
    cv::fillConvexPoly(img, tip, red);
    cv::line(img, chord_pt(0.75, 0.72), chord_pt(kWingTipY - 0.4, 0.72), panel, 1);  // flap / aileron hinge
    cv::line(img, chord_pt(0.75, 0.3), chord_pt(kWingTipY - 0.4, 0.3), panel, 1);    // spar
    for (double y : {1.2, 2.0, 3.1, 4.4, 5.8, 7.0})
      cv::line(img, chord_pt(y, 0.1), chord_pt(y, 1.0), panel, 1);
  }
  // --- Nacelles (cols 768-959) and spinners (cols 960-1023) in rows 256-383.
  {
    auto nac_rect = [&](double x0, double x1, double th0, double th1, const cv::Scalar& col) {
      const int c0 = px(nac_u(x0)), c1 = px(nac_u(x1)), r0 = py(nac_v(th0)), r1 = py(nac_v(th1));
      cv::rectangle(img, cv::Rect(c0, r0, std::max(c1 - c0, 1), std::max(r1 - r0, 1)), col, cv::FILLED);
    };
    nac_rect(2.95, -2.2, kPi / 2 - 0.12, kPi / 2 + 0.12, blue);
    nac_rect(2.95, -2.2, 3 * kPi / 2 - 0.12, 3 * kPi / 2 + 0.12, blue);
    nac_rect(1.0, 0.55, kPi / 2 - 0.5, kPi / 2 + 0.4, dark);  // exhaust stacks
    nac_rect(1.0, 0.55, 3 * kPi / 2 - 0.4, 3 * kPi / 2 + 0.5, dark);
    nac_rect(2.95, 2.7, 0.0, 2 * kPi, grey);
    for (double x : {2.2, 1.4, 0.0, -1.0}) {
      cv::line(img, cv::Point(px(nac_u(x)), 256), cv::Point(px(nac_u(x)), 383), panel, 1);
    }
    cv::rectangle(img, cv::Rect(960, 256, 64, 128), cv::Scalar(70, 68, 66), cv::FILLED);
  }
  // --- Tailplane (rows 384-447, cols 0-511) and fin (rows 384-511, cols 512-1023).
  {
    cv::rectangle(img, cv::Rect(0, 384, px(ht_u(-2.55)), 64), red, cv::FILLED);
    cv::rectangle(img, cv::Rect(px(ht_u(2.55)), 384, 512 - px(ht_u(2.55)), 64), red, cv::FILLED);
    cv::rectangle(img, cv::Rect(0, py(ht_v(-6.5)), 512, 4), dark, cv::FILLED);
    auto fin_band = [&](double z0, double z1, const cv::Scalar& col) {
      cv::rectangle(img, cv::Rect(512, py(fin_v(z0)), 512, std::max(py(fin_v(z1)) - py(fin_v(z0)), 1)), col,
                    cv::FILLED);
    };
    fin_band(-2.55, -2.25, blue);
    fin_band(-2.2, -2.12, red);
    fin_band(-1.3, -1.22, blue);
    cv::line(img, cv::Point(512, py(fin_v(-1.8))), cv::Point(1023, py(fin_v(-1.8))), panel, 1);
  }

  // Speckle: fine per-texel noise plus a coarser mottle, so a stereo matcher finds texture at any
  // distance. Fixed seed: the model is the same on every run.
  cv::RNG rng(0x5eed);
  cv::Mat fine(kTexH, kTexW, CV_32F), coarse_small(kTexH / 8, kTexW / 8, CV_32F), coarse;
  rng.fill(fine, cv::RNG::NORMAL, 0.0, 13.0);
  rng.fill(coarse_small, cv::RNG::NORMAL, 0.0, 9.0);
  cv::resize(coarse_small, coarse, fine.size(), 0, 0, cv::INTER_CUBIC);
  cv::Mat noise = fine + coarse, img_f;
  img.convertTo(img_f, CV_32FC3);
  cv::Mat noise3;
  cv::merge(std::vector<cv::Mat>{noise, noise, noise}, noise3);
  img_f += noise3;
  img_f.convertTo(img, CV_8UC3);  // saturating

  cv::Mat rgba;
  cv::cvtColor(img, rgba, cv::COLOR_BGR2RGBA);
  auto tex = std::make_shared<Texture>();
  tex->width = kTexW;
  tex->height = kTexH;
  tex->rgba.assign(rgba.data, rgba.data + rgba.total() * 4);
  return tex;
}

// Lifting surface from airfoil sections: each section is (leading edge point, chord, t/c); the
// outline lies in the plane spanned by the chord (-x) and `thickness_dir`.
Loft airfoil_loft(const std::vector<std::tuple<Eigen::Vector3d, double, double>>& stations,
                  const Eigen::Vector3d& thickness_dir) {
  Loft L;
  for (const auto& [le, chord, tc] : stations) {
    Section s;
    for (const auto& [f, h] : naca_outline(tc)) {
      s.push_back((le + Eigen::Vector3d(-f * chord, 0, 0) + h * chord * thickness_dir).cast<float>());
    }
    L.sections.push_back(s);
  }
  L.ring_crease = airfoil_creases(L.sections.front().size());
  return L;
}

}  // namespace

Model make_builtin_receiver(Eigen::Vector3d* receptacle_m) {
  const std::shared_ptr<const Texture> tex = livery_texture();
  const Vector3f white(1, 1, 1);
  Model model;

  // Fuselage: lofted ellipses, poles at the nose and the tail cone; cylindrical uv.
  {
    Builder b;
    Loft L;
    std::vector<double> xs;
    for (const auto& s : kFuselage) {
      L.sections.push_back(ellipse_x(s.x, 0.0, s.zc, s.a, s.b, kFuselageSegments));
      xs.push_back(s.x);
    }
    L.uv = [xs](int i, int j) { return Vector2f(fus_u(xs[i]), fus_v(2 * kPi * j / kFuselageSegments)); };
    loft(b, L);
    model.meshes.push_back(b.finish("fuselage", white, tex));
  }
  // Wings (left and right), planar uv from above.
  for (double side : {1.0, -1.0}) {
    Builder b;
    std::vector<std::tuple<Eigen::Vector3d, double, double>> st;
    for (double y : {kWingRootY, kWingTipY}) {
      st.emplace_back(Eigen::Vector3d(wing_le(y), side * y, wing_z(y)), wing_chord(y),
                      y == kWingRootY ? kWingRootTc : kWingTipTc);
    }
    Loft L = airfoil_loft(st, -Eigen::Vector3d::UnitZ());  // upper surface towards -z (up)
    L.uv = [&L](int i, int j) {
      const Vector3f& p = L.sections[i][j % L.sections[i].size()];
      return Vector2f(wing_u(p.y()), wing_v(p.x()));
    };
    loft(b, L);
    model.meshes.push_back(b.finish(side > 0 ? "wing_right" : "wing_left", white, tex));
  }
  // Engine nacelles and spinners (cylindrical uv into the nacelle / spinner strips).
  for (double side : {1.0, -1.0}) {
    const double y = side * kNacelleY;
    constexpr int n = 24;
    {
      Builder b;
      Loft L;
      const FuselageStation nac[] = {{2.95, 0.00, 0.24, 0.26},  {2.75, 0.01, 0.33, 0.38},
                                     {2.30, 0.03, 0.39, 0.46},  {1.00, 0.05, 0.40, 0.48},
                                     {-0.60, 0.02, 0.34, 0.40}, {-1.60, -0.02, 0.20, 0.24},
                                     {-2.20, -0.05, 0.00, 0.00}};
      std::vector<double> xs;
      for (const auto& s : nac) {
        L.sections.push_back(ellipse_x(s.x, y, s.zc, s.a, s.b, n));
        xs.push_back(s.x);
      }
      L.uv = [xs](int i, int j) { return Vector2f(nac_u(xs[i]), nac_v(2 * kPi * j / n)); };
      loft(b, L);
      model.meshes.push_back(b.finish(side > 0 ? "nacelle_right" : "nacelle_left", white, tex));
    }
    {
      Builder b;
      Loft L;
      const std::pair<double, double> prof[] = {
          {3.60, 0.0}, {3.52, 0.09}, {3.38, 0.16}, {3.18, 0.21}, {2.95, 0.23}};
      for (const auto& [x, r] : prof) L.sections.push_back(ellipse_x(x, y, 0.0, r, r, n));
      L.uv = [](int i, int j) {
        return Vector2f(static_cast<float>((960.5 + 60.0 * i / 4) / kTexW), nac_v(2 * kPi * j / n));
      };
      loft(b, L);
      model.meshes.push_back(b.finish(side > 0 ? "spinner_right" : "spinner_left", white, tex));
    }
  }
  // Vertical fin (root buried in the tail cone) carrying the T-tail.
  {
    Builder b;
    Loft L = airfoil_loft(
        {{Eigen::Vector3d(-4.75, 0, -0.70), 2.55, 0.12}, {Eigen::Vector3d(-6.55, 0, -2.98), 1.25, 0.10}},
        Eigen::Vector3d::UnitY());
    L.uv = [&L](int i, int j) {
      const Vector3f& p = L.sections[i][j % L.sections[i].size()];
      return Vector2f(fin_u(p.x()), fin_v(p.z()));
    };
    loft(b, L);
    model.meshes.push_back(b.finish("fin", white, tex));
  }
  // Horizontal tailplane on top of the fin, one piece through the centre line.
  {
    Builder b;
    Loft L = airfoil_loft({{Eigen::Vector3d(-6.95, -2.8, -2.98), 0.85, 0.10},
                           {Eigen::Vector3d(-6.45, 0.0, -2.98), 1.40, 0.12},
                           {Eigen::Vector3d(-6.95, 2.8, -2.98), 0.85, 0.10}},
                          -Eigen::Vector3d::UnitZ());
    L.uv = [&L](int i, int j) {
      const Vector3f& p = L.sections[i][j % L.sections[i].size()];
      return Vector2f(ht_u(p.y()), ht_v(p.x()));
    };
    loft(b, L);
    model.meshes.push_back(b.finish("tailplane", white, tex));
  }

  if (receptacle_m) {
    // Exactly the fuselage's top-centre vertex at the receptacle station, so it lies on the surface.
    for (const auto& s : kFuselage) {
      if (s.x == kReceptacleX) {
        *receptacle_m = Eigen::Vector3f(Eigen::Vector3d(s.x, 0.0, s.zc - s.b).cast<float>()).cast<double>();
      }
    }
  }
  return model;
}

// ----------------------------------------------------------------------------------------------

Pose boom_pose(const Eigen::Vector3d& pivot_body_m, const BoomArticulation& a) {
  // Rz(pi) turns the boom x axis aft; Ry(-elevation) tilts it down (about the boom's own y axis).
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(kPi - a.azimuth_rad, Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(-a.elevation_rad, Eigen::Vector3d::UnitY()))
                                .toRotationMatrix();
  return Pose::from(R, pivot_body_m);
}

Pose telescope_pose(const BoomArticulation& a) {
  return Pose::from(Eigen::Matrix3d::Identity(), Eigen::Vector3d(a.extension_m, 0.0, 0.0));
}

}  // namespace augrig
