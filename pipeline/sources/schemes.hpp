// The source URI schemes' openers, one file per scheme under pipeline/sources/, and the URI
// parameter parsing they share. open_sources() (pipeline/sources.cpp) parses the URI and calls the
// opener its scheme names in the table kSchemes; a new scheme is one file here, its opener's
// declaration below and one line in that table. Internal to augrig_pipeline: commands open sources
// through pipeline/sources.hpp.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "capture/source_uri.hpp"
#include "core/expected.hpp"
#include "core/frame.hpp"
#include "pipeline/sources.hpp"

namespace augrig::pipeline {

// ---- Shared by the openers (defined in pipeline/sources.cpp) ----

// "source URI 'TEXT': WHAT".
Error uri_error(const SourceUri& u, const std::string& what);

// bayer=RG|GR|GB|BG (sim://, files://): the raw mosaic's pixel format; anything else is an error.
Expected<PixelFormat> bayer_param(const SourceUri& u);

// Where a played file begins (replay://DIR, euroc://DIR): from_frame=N, the N-th frame (or pair),
// or seek_s=S, S seconds after the first; the two exclude each other. Neither: frame 0.
struct PlaybackStart {
  std::size_t frame = 0;
  std::optional<std::int64_t> offset_ns;
};
Expected<PlaybackStart> playback_start(const SourceUri& u);

// ---- One opener per scheme (each in pipeline/sources/SCHEME_scheme.cpp) ----

Expected<OpenedSource> open_sim(const SourceUri& u);            // sim_scheme.cpp
Expected<OpenedSource> open_replay(const SourceUri& u);         // replay_scheme.cpp (and MCAP files)
Expected<OpenedSource> open_files(const SourceUri& u);          // files_scheme.cpp
Expected<OpenedSource> open_euroc(const SourceUri& u);          // euroc_scheme.cpp
Expected<OpenedSource> open_stereo(const SourceUri& u);         // stereo_scheme.cpp
Expected<OpenedSource> open_single_camera(const SourceUri& u);  // camera_scheme.cpp: aravis, v4l2

// One camera's source (aravis://, v4l2://), a stereo:// rig's left or right (camera_scheme.cpp).
Expected<std::unique_ptr<FrameSource>> open_camera(const SourceUri& u, CameraId camera);

}  // namespace augrig::pipeline
