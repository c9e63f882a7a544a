// Frame sources by URI (capture/source_uri.hpp): opens sim://, replay://, files://, euroc:// and
// stereo://'s aravis:// or v4l2:// cameras, and composes them into the StereoSource the live
// pipeline reads. Each scheme is one file under pipeline/sources/ (its URI syntax and parameters at
// its top), found by its name in sources.cpp's table: the one place that knows every scheme, so
// capture/ needs neither the simulator nor the recorder.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "capture/source_uri.hpp"
#include "capture/stereo_source.hpp"
#include "core/frame.hpp"
#include "pipeline/image_folder_source.hpp"
#include "render/rig.hpp"
#include "sim/flight.hpp"
#include "sim/flight_source.hpp"
#include "sim/scenario.hpp"
#include "sim/sensors.hpp"
#include "sim/sim_clock.hpp"

namespace augrig::recorder {
class ReplaySource;
}

namespace augrig::pipeline {

// A simulated flight, computed once for the run and shared by the rendered cameras, the simulated
// nav streams and the truth.
struct SimulatedFlight {
  sim::Scenario scenario;
  std::unique_ptr<sim::Flight> flight;
  sim::SensorLogs logs;
};

// The simulated flight's phase of each pair (by its left frame's time), from the truths of the
// frames its cameras deliver (sim::frame_truths), for PipelineParts::phase_of.
std::function<std::string(const StereoFrame&)> sim_phases(const std::vector<sim::FrameTruth>& truths);

// What a source URI opened into, beyond its FrameSources: what the pipeline needs to know about it.
struct OpenedSourceInfo {
  bool live = false;                          // cameras (true) or a file / simulation
  std::string scenario;                       // sim://: the scenario's name, for nav truth
  std::shared_ptr<const SimulatedFlight> sim;  // sim://: the scenario, its truth and sensor logs
  std::shared_ptr<sim::SimClock> sim_clock;   // sim://: GPS time to host time for this run
  // replay://: the recording's player (owned by the source list, then by the StereoSource), for
  // pause, step and seek.
  recorder::ReplaySource* replay = nullptr;
  // files://: the image folder or index (owned like `replay`), for its entries' names and places.
  const ImageFolderSource* image_files = nullptr;
};

struct OpenedSource : OpenedSourceInfo {
  std::vector<std::unique_ptr<FrameSource>> sources;  // one (both cameras) or two (left, right)
  StereoSourceOptions options;                        // pairing and queueing for these sources
};

// `uri`: one stereo-capable URI (sim://, replay://, stereo:[..]//{L}{R}); or, with `right_uri`, the
// two cameras' URIs (the rig's per-camera `source` keys) composed as stereo:[PAIRING]//{L}{R},
// PAIRING being the rig's `pairing` section (its defaults are stereo://'s).
Expected<OpenedSource> open_sources(const std::string& uri, const std::string& right_uri = "",
                                    const RigPairing& pairing = {});

// The StereoSource of an OpenedSource (starts its capture threads).
Expected<std::unique_ptr<StereoSource>> start_stereo(OpenedSource opened);

}  // namespace augrig::pipeline
