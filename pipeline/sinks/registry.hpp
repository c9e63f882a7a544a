// The sink registry: further outputs chosen on the command line as "SCHEME:ARGUMENT"
// (`--sink video:flight.mp4`), like rosbag2's storage plugins. Each sink is one file under
// pipeline/sinks/ and one line in registry.cpp's table (its scheme, its usage, its factory);
// nothing else names it. A sink made here follows the built-in ones (frame_sink.hpp's order).
#pragma once

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/expected.hpp"
#include "pipeline/frame_sink.hpp"
#include "render/rig.hpp"

namespace augrig::recorder {
class RecordingReader;
struct EurocExportOptions;
struct EurocExportReport;
}  // namespace augrig::recorder

namespace augrig::pipeline {

// What a sink may need to open: the rig (its cameras' sizes, their poses on the tanker).
struct SinkSetup {
  const Rig& rig;
  // Metadata a file sink stores with its frames (where they came from); the rig is added by it.
  std::map<std::string, std::string> meta = {};
  // A recording whose nav inputs a file sink copies at its close (export --reaugment's); null: none.
  const recorder::RecordingReader* nav_from = nullptr;
  // The recording `augrig replay REC` plays (its folder); empty for other sources. The euroc sink's
  // `nav` option opens it for the clock and nav inputs, as export --reaugment does (a campaign
  // shard's export).
  std::string replayed = {};
};

// A sink from "SCHEME:ARGUMENT"; an unknown scheme or a bad argument is an Error naming it and
// listing what is known.
Expected<std::unique_ptr<FrameSink>> make_sink(const std::string& spec, const SinkSetup& setup);
// Each registered sink's usage line, for --help and docs/CLI.md.
std::vector<std::string> sink_usages();

// The registered factories (one file each). `arg` is the part after "SCHEME:".
Expected<std::unique_ptr<FrameSink>> make_video_sink(const std::string& arg, const SinkSetup& setup);
Expected<std::unique_ptr<FrameSink>> make_tum_sink(const std::string& arg, const SinkSetup& setup);
Expected<std::unique_ptr<FrameSink>> make_mcap_sink(const std::string& arg, const SinkSetup& setup);
Expected<std::unique_ptr<FrameSink>> make_euroc_sink(const std::string& arg, const SinkSetup& setup);
Expected<std::unique_ptr<FrameSink>> make_kitti_sink(const std::string& arg, const SinkSetup& setup);
Expected<std::unique_ptr<FrameSink>> make_middlebury_sink(const std::string& arg, const SinkSetup& setup);
Expected<std::unique_ptr<FrameSink>> make_coco_sink(const std::string& arg, const SinkSetup& setup);
Expected<std::unique_ptr<FrameSink>> make_yolo_sink(const std::string& arg, const SinkSetup& setup);
// The euroc sink with the export's every option (export --reaugment); `report`, when given, gets
// what it wrote at its close.
Expected<std::unique_ptr<FrameSink>> make_euroc_sink(const std::string& dir,
                                                     const recorder::EurocExportOptions& options,
                                                     const SinkSetup& setup,
                                                     recorder::EurocExportReport* report);

}  // namespace augrig::pipeline
