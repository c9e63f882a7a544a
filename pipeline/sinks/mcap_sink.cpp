// An MCAP file of ROS 2 messages as a sink (`--sink mcap:OUT.mcap`): each pair as export_mcap()
// writes a recorded frame (recorder/mcap_export.hpp, docs/MCAP.md), through the same writer, so a
// run, a replay with another rig, scene, boom or look, or a simulated flight gives the file
// `augrig export --format mcap` gives, which `augrig replay OUT.mcap` plays back. The images go in
// as views of the pair (nothing copied); the file's metadata holds the run's rig (and what the
// setup adds: where the frames came from), and, when the setup names a recording (export
// --reaugment), that recording's nav inputs follow the frames. Options after the file name:
// `no-augmented`, `no-masks`. The file is OUT.mcap.part until the run closes it cleanly.
#include <cstdlib>
#include <sstream>

#include "pipeline/report.hpp"
#include "pipeline/sinks/registry.hpp"
#include "recorder/mcap_export.hpp"

namespace augrig::pipeline {

namespace {

class McapSink final : public FrameSink {
 public:
  McapSink(std::string path, recorder::McapExportOptions options, const SinkSetup& setup)
      : path_(std::move(path)),
        options_(std::move(options)),
        rig_(setup.rig),
        meta_(setup.meta),
        nav_from_(setup.nav_from) {}

  Status open() {
    meta_["rig_yaml"] = rig_to_yaml(rig_);  // the rig of this run's augmentation
    auto w = recorder::McapFrameWriter::create(path_, options_, meta_, rig_, report_);
    if (!w) return make_error("mcap sink: ", w.error().message);
    writer_ = std::move(*w);
    return {};
  }

  SinkNeeds needs() const override { return {.whole_images = options_.augmented}; }

  Status consume(PairContext& pair) override {
    recorder::McapFrame f;
    f.raw = &pair.raw;
    if (pair.result && options_.augmented) pair.make_whole();
    if (const StereoResult* r = pair.result) {
      const ViewResult* views[2] = {&r->left, &r->right};
      for (int c = 0; c < 2; ++c) {
        if (options_.augmented && !views[c]->augmented.empty()) f.augmented[c] = views[c]->augmented.cview();
        if (options_.masks && !views[c]->mask.empty()) f.mask[c] = views[c]->mask.cview();
      }
      f.stats = &r->stats;
    }
    record_scene(pair, rig_, f);  // the scene it was augmented in, as a recording keeps it
    // A recording's frame keeps its index (as export_mcap writes it), so that the files of a
    // flight's shards join into the file of the whole flight (merge_mcap); else the count.
    const std::uint64_t index = pair.position ? pair.position->index : report_.frames;
    ++report_.frames;
    return writer_->write(f, index, "pair " + std::to_string(pair.pair));
  }

  Status close(PipelineReport& report) override {
    if (!writer_) return {};
    if (nav_from_)
      if (Status s = writer_->write_nav(*nav_from_); !s) return make_error("mcap sink: ", s.error().message);
    const Status s = writer_->finish();
    writer_.reset();
    if (!s) return make_error("mcap sink: ", s.error().message);
    std::ostringstream line;
    line << path_ << ": " << report_.frames_written << " stereo frame(s), " << report_.messages << " messages in "
         << report_.chunks << " zstd chunk(s), " << report_.bytes << " bytes";
    report.outputs.push_back(line.str());
    for (const std::string& p : report_.problems) report.outputs.push_back(path_ + ": " + p);
    return {};
  }

 private:
  std::string path_;
  recorder::McapExportOptions options_;
  Rig rig_;  // a copy: the parts it came from move into the pipeline
  std::map<std::string, std::string> meta_;
  recorder::McapExportReport report_;
  const recorder::RecordingReader* nav_from_;
  std::unique_ptr<recorder::McapFrameWriter> writer_;
};

// "NAME" (the default) or "NAME=V" with V a whole number lo..hi.
Expected<int> option_number(const std::string& opt, const std::string& name, int fallback, int lo, int hi) {
  if (opt == name) return fallback;
  const std::string v = opt.substr(name.size() + 1);
  char* end = nullptr;
  const long n = std::strtol(v.c_str(), &end, 10);
  if (v.empty() || *end || n < lo || n > hi)
    return make_error("mcap sink: ", opt, ": expected ", name, " or ", name, "=N with N a whole number ", lo,
                      "..", hi);
  return static_cast<int>(n);
}

}  // namespace

Expected<std::unique_ptr<FrameSink>> make_mcap_sink(const std::string& arg, const SinkSetup& setup) {
  std::istringstream in(arg);
  std::string path;
  std::getline(in, path, ',');
  recorder::McapExportOptions o;
  o.nav = setup.nav_from != nullptr;
  for (std::string opt; std::getline(in, opt, ',');) {
    if (opt == "no-augmented")
      o.augmented = false;
    else if (opt == "no-masks")
      o.masks = false;
    else if (opt == "jpeg" || opt.rfind("jpeg=", 0) == 0) {
      o.jpeg = true;
      auto q = option_number(opt, "jpeg", 90, 1, 100);
      if (!q) return q.error();
      o.jpeg_quality = *q;
    } else if (opt == "h264" || opt.rfind("h264=", 0) == 0) {
      o.h264 = true;
      auto crf = option_number(opt, "h264", 23, 0, 51);
      if (!crf) return crf.error();
      o.h264_crf = *crf;
    } else if (opt.rfind("gop=", 0) == 0) {
      auto n = option_number(opt, "gop", 30, 1, 100000);
      if (!n) return n.error();
      o.h264_gop_frames = *n;
    } else
      return make_error("mcap sink: ", opt,
                        ": unknown option (expected no-augmented, no-masks, jpeg[=Q], h264[=CRF] or gop=N)");
  }
  if (o.jpeg && o.h264) return make_error("mcap sink: jpeg or h264, not both");
  if (path.empty()) return make_error("mcap sink: expected a file name (mcap:OUT.mcap)");
  auto sink = std::make_unique<McapSink>(path, o, setup);
  if (Status st = sink->open(); !st) return st.error();
  return std::unique_ptr<FrameSink>(std::move(sink));
}

}  // namespace augrig::pipeline
