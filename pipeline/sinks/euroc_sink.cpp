// A EuRoC/ASL dataset folder as a sink (`--sink euroc:DIR`): each pair written as `augrig export`
// writes a recorded frame (recorder/euroc.hpp, docs/REPLAY.md), through the same writer
// (recorder::EurocWriter): cam0, cam1 (raw), cam0_augmented, cam1_augmented, cam0_mask, cam1_mask,
// with ground-truth the receiver depth, correspondence and stereo classes; poses.csv, stats.csv,
// phases.csv (from the run's "phase:" events), frames.csv, rig.yaml and the receiver's states at the
// close. Timestamps are the frames' own (their clock in each sensor.yaml), or, when the setup names
// the recording the pairs were replayed from (export --reaugment), on the clock its export would
// choose, with its nav inputs (imu0, nav/). The images are encoded on worker threads from copies
// of the pair (the pair's buffers go back to the pipeline). Options after the folder: `no-augmented`,
// `no-masks`, `no-plot`, `ground-truth`, and `nav`: a replay's pairs on the clock of the recording
// replayed, with its nav inputs (what export --reaugment writes; a campaign shard's export, joined
// per flight by recorder::merge_euroc). OUT/INCOMPLETE stays until the run closes it cleanly.
#include <sstream>

#include "pipeline/outputs.hpp"
#include "pipeline/report.hpp"
#include "pipeline/sinks/registry.hpp"
#include "recorder/euroc.hpp"

namespace augrig::pipeline {

namespace {

class EurocSink final : public FrameSink {
 public:
  // `own_nav`: the reader options.nav_from points to, when the sink opened it (the `nav` option).
  EurocSink(std::string dir, recorder::EurocExportOptions options, const SinkSetup& setup,
            recorder::EurocExportReport* report_out, std::unique_ptr<recorder::RecordingReader> own_nav = {})
      : dir_(std::move(dir)),
        options_(std::move(options)),
        rig_(setup.rig),
        report_out_(report_out),
        own_nav_(std::move(own_nav)) {
    if (setup.nav_from) options_.nav_from = setup.nav_from;
  }

  Status open() {
    auto w = recorder::EurocWriter::create(dir_, options_, rig_, nullptr,
                                           options_.nav_from ? options_.nav_from->path() : dir_, report_);
    if (!w) return make_error("euroc sink: ", w.error().message);
    writer_ = std::move(*w);
    return {};
  }

  SinkNeeds needs() const override { return {.whole_images = options_.augmented}; }

  Status consume(PairContext& pair) override {
    if (pair.result && options_.augmented) pair.make_whole();
    recorder::FrameRecord r =
        pair.result ? frame_record(*pair.result, options_.ground_truth) : recorder::FrameRecord{};
    if (!options_.augmented) r.augmented = {};
    r.raw = pair.raw;  // a copy: the encoders keep it until written
    record_scene(pair, rig_, r);
    const std::size_t index = pair.position ? pair.position->index : frames_;
    ++frames_;
    if (Status s = writer_->add(index, std::move(r)); !s)
      return make_error("euroc sink: ", s.error().message);
    return {};
  }

  void event(const SinkEvent& e) override { events_.push_back({e.t_ns, e.clock, e.text}); }

  Status close(PipelineReport& report) override {
    if (!writer_) return {};
    const Status s = writer_->finish(events_);
    writer_.reset();
    if (report_out_) *report_out_ = report_;
    if (!s) return make_error("euroc sink: ", s.error().message);
    std::ostringstream line;
    line << dir_ << ": " << report_.frames_written << " stereo frame(s) in the EuRoC layout (mav0/cam0, cam1"
         << (report_.augmented_written ? ", cam0_augmented, cam1_augmented" : "")
         << (report_.masks_written ? ", cam0_mask, cam1_mask" : "")
         << (report_.ground_truth_written ? ", the ground truth" : "") << "), clock "
         << to_string(report_.clock);
    report.outputs.push_back(line.str());
    for (const std::string& p : report_.problems) report.outputs.push_back(dir_ + ": problem: " + p);
    return {};
  }

 private:
  std::string dir_;
  recorder::EurocExportOptions options_;
  Rig rig_;  // a copy: the parts it came from move into the pipeline
  recorder::EurocExportReport* report_out_;
  recorder::EurocExportReport report_;
  std::unique_ptr<recorder::RecordingReader> own_nav_;  // before writer_: destroyed after it
  std::unique_ptr<recorder::EurocWriter> writer_;
  std::vector<recorder::EventRecord> events_;
  std::size_t frames_ = 0;
};

}  // namespace

Expected<std::unique_ptr<FrameSink>> make_euroc_sink(const std::string& dir,
                                                     const recorder::EurocExportOptions& options,
                                                     const SinkSetup& setup,
                                                     recorder::EurocExportReport* report) {
  if (dir.empty()) return make_error("euroc sink: expected a folder (euroc:DIR)");
  auto sink = std::make_unique<EurocSink>(dir, options, setup, report);
  if (Status st = sink->open(); !st) return st.error();
  return std::unique_ptr<FrameSink>(std::move(sink));
}

Expected<std::unique_ptr<FrameSink>> make_euroc_sink(const std::string& arg, const SinkSetup& setup) {
  std::istringstream in(arg);
  std::string dir;
  std::getline(in, dir, ',');
  recorder::EurocExportOptions o;
  bool nav = false;
  for (std::string opt; std::getline(in, opt, ',');) {
    if (opt == "no-augmented")
      o.augmented = false;
    else if (opt == "no-masks")
      o.masks = false;
    else if (opt == "no-plot")
      o.plot = false;
    else if (opt == "ground-truth")
      o.ground_truth = true;
    else if (opt == "nav")
      nav = true;
    else
      return make_error("euroc sink: ", opt,
                        ": unknown option (expected no-augmented, no-masks, no-plot, ground-truth or nav)");
  }
  // The recording replayed, read again by a reader of the sink's own (the source's belong to its threads).
  std::unique_ptr<recorder::RecordingReader> replayed;
  if (nav && !setup.nav_from) {
    if (setup.replayed.empty())
      return make_error(
          "euroc sink: nav: the clock and nav inputs of the recording replayed; only `augrig "
          "replay REC` replays one");
    auto r = recorder::RecordingReader::open(setup.replayed);
    if (!r) return make_error("euroc sink: nav: ", r.error().message);
    replayed = std::move(*r);
    o.nav_from = replayed.get();
  }
  if (dir.empty()) return make_error("euroc sink: expected a folder (euroc:DIR)");
  auto sink = std::make_unique<EurocSink>(dir, o, setup, nullptr, std::move(replayed));
  if (Status st = sink->open(); !st) return st.error();
  return std::unique_ptr<FrameSink>(std::move(sink));
}

}  // namespace augrig::pipeline
