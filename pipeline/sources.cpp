// Sources by URI: the URI parsed, its scheme's opener found in kSchemes (one file per scheme
// under pipeline/sources/, declared in pipeline/sources/schemes.hpp), and what the openers share.
#include "pipeline/sources.hpp"

#include <iomanip>
#include <map>
#include <sstream>

#include "pipeline/sources/schemes.hpp"

namespace augrig::pipeline {

// ---- Shared by the openers ----

Error uri_error(const SourceUri& u, const std::string& what) {
  return make_error("source URI '", u.text, "': ", what);
}

Expected<PixelFormat> bayer_param(const SourceUri& u) {
  const std::string b = u.get("bayer");
  const PixelFormat f = b == "RG"   ? PixelFormat::kBayerRG8
                        : b == "GR" ? PixelFormat::kBayerGR8
                        : b == "GB" ? PixelFormat::kBayerGB8
                        : b == "BG" ? PixelFormat::kBayerBG8
                                    : PixelFormat::kMono8;
  if (f == PixelFormat::kMono8) return uri_error(u, "bayer: expected RG, GR, GB or BG, got '" + b + "'");
  return f;
}

Expected<PlaybackStart> playback_start(const SourceUri& u) {
  PlaybackStart start;
  if (u.has("from_frame") && u.has("seek_s")) return uri_error(u, "from_frame and seek_s exclude each other");
  if (u.has("from_frame")) {
    auto n = u.get_integer("from_frame", 0, 0, 1LL << 40);
    if (!n) return n.error();
    start.frame = static_cast<std::size_t>(*n);
  }
  if (u.has("seek_s")) {
    auto t = u.get_number("seek_s", 0, 0, 1e9);
    if (!t) return t.error();
    start.offset_ns = s_to_ns(*t);
  }
  return start;
}

namespace {

// The schemes, one opener each.
struct Scheme {
  const char* name;
  Expected<OpenedSource> (*open)(const SourceUri&);
};
constexpr Scheme kSchemes[] = {
    {"sim", open_sim},               // sources/sim_scheme.cpp
    {"replay", open_replay},         // sources/replay_scheme.cpp: recordings and MCAP files
    {"files", open_files},           // sources/files_scheme.cpp
    {"euroc", open_euroc},           // sources/euroc_scheme.cpp
    {"stereo", open_stereo},         // sources/stereo_scheme.cpp
    {"aravis", open_single_camera},  // sources/camera_scheme.cpp
    {"v4l2", open_single_camera},    // sources/camera_scheme.cpp
};

// A left and a right URI as one stereo:[..]//{L}{R} with the rig's pairing.
SourceUri stereo_of(const SourceUri& left, const std::string& uri, const SourceUri& right,
                    const std::string& right_uri, const RigPairing& pairing) {
  SourceUri stereo;
  std::ostringstream tolerance;
  tolerance << std::setprecision(12) << pairing.tolerance_us;
  stereo.scheme = "stereo";
  stereo.params = {{"tolerance_us", tolerance.str()},
                   {"mode", pairing.mode},
                   {"clock", pairing.clock},
                   {"queue", std::to_string(pairing.queue)}};
  std::string params;
  for (const auto& [key, value] : stereo.params) params += (params.empty() ? "" : ",") + key + "=" + value;
  stereo.text = "stereo:[" + params + "]//{" + uri + "}{" + right_uri + "}";
  stereo.children = {left, right};
  return stereo;
}

}  // namespace

Expected<OpenedSource> open_sources(const std::string& uri, const std::string& right_uri,
                                    const RigPairing& pairing) {
  auto parsed = parse_source_uri(uri);
  if (!parsed) return parsed.error();
  SourceUri u = std::move(*parsed);
  if (!right_uri.empty()) {
    auto right = parse_source_uri(right_uri);
    if (!right) return right.error();
    u = stereo_of(u, uri, *right, right_uri, pairing);
  }
  for (const Scheme& scheme : kSchemes)
    if (u.scheme == scheme.name) return scheme.open(u);
  return uri_error(
      u, "unknown scheme '" + u.scheme + "'; expected aravis, v4l2, sim, replay, euroc, files or stereo");
}

Expected<std::unique_ptr<StereoSource>> start_stereo(OpenedSource opened) {
  return StereoSource::create(std::move(opened.sources), opened.options);
}

std::function<std::string(const StereoFrame&)> sim_phases(const std::vector<sim::FrameTruth>& truths) {
  auto by_t = std::make_shared<std::map<TimestampNs, std::string>>();
  for (const sim::FrameTruth& f : truths)
    if (f.camera == 0) (*by_t)[f.t_camera_ns] = f.phase;
  return [by_t](const StereoFrame& frame) -> std::string {
    const auto it = by_t->find(frame.left.t_ns);
    return it == by_t->end() ? std::string() : it->second;
  };
}

}  // namespace augrig::pipeline
