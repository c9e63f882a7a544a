// A EuRoC/ASL dataset folder as a sink (`--sink euroc:DIR`): each pair written as `augrig export`
// writes a recorded frame (recorder/euroc.hpp, docs/REPLAY.md), through the same writer
// (recorder::EurocWriter): cam0, cam1 (raw), cam0_augmented, cam1_augmented, cam0_mask, cam1_mask,
// with ground-truth the receiver depth, correspondence and stereo classes; poses.csv, stats.csv,
// phases.csv (from the run's "phase:" events), frames.csv, rig.yaml and the receiver's states at the
// close. Timestamps are the frames' own (their clock in each sensor.yaml), or, when the setup names
// the recording the pairs were replayed from (export --reaugment), on the clock its export would
// choose, with its nav inputs (imu0, nav/). The images are encoded on worker threads from copies
// of the pair (the pair's buffers go back to the pipeline). Options after the folder: `no-augmented`,
// `no-masks`, `no-plot`, `ground-truth`. OUT/INCOMPLETE stays until the run closes it cleanly.
#include <sstream>

#include "pipeline/outputs.hpp"
#include "pipeline/report.hpp"
#include "pipeline/sinks/registry.hpp"
#include "recorder/euroc.hpp"

namespace augrig::pipeline {

namespace {

class EurocSink final : public FrameSink {
 public:
  EurocSink(std::string dir, recorder::EurocExportOptions options, const SinkSetup& setup,
            recorder::EurocExportReport* report_out)
      : dir_(std::move(dir)), options_(std::move(options)), rig_(setup.rig), report_out_(report_out) {
    options_.nav_from = setup.nav_from;
  }

  Status open() {
    auto w = recorder::EurocWriter::create(dir_, options_, rig_, nullptr, options_.nav_from ? options_.nav_from->path() : dir_,
                                           report_);
    if (!w) return make_error("euroc sink: ", w.error().message);
    writer_ = std::move(*w);
    return {};
  }

  SinkNeeds needs() const override { return {.whole_images = options_.augmented}; }

  Status consume(PairContext& pair) override {
    if (pair.result && options_.augmented) pair.make_whole();
    recorder::FrameRecord r = pair.result ? frame_record(*pair.result, options_.ground_truth) : recorder::FrameRecord{};
    if (!options_.augmented) r.augmented = {};
    r.raw = pair.raw;  // a copy: the encoders keep it until written
    record_scene(pair, rig_, r);
    const std::size_t index = pair.position ? pair.position->index : frames_;
    ++frames_;
    if (Status s = writer_->add(index, std::move(r)); !s) return make_error("euroc sink: ", s.error().message);
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
         << (report_.ground_truth_written ? ", the ground truth" : "") << "), clock " << to_string(report_.clock);
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
  std::unique_ptr<recorder::EurocWriter> writer_;
  std::vector<recorder::EventRecord> events_;
  std::size_t frames_ = 0;
};

}  // namespace

Expected<std::unique_ptr<FrameSink>> make_euroc_sink(const std::string& dir, const recorder::EurocExportOptions& options,
                                                     const SinkSetup& setup, recorder::EurocExportReport* report) {
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
  for (std::string opt; std::getline(in, opt, ',');) {
    if (opt == "no-augmented")
      o.augmented = false;
    else if (opt == "no-masks")
      o.masks = false;
    else if (opt == "no-plot")
      o.plot = false;
    else if (opt == "ground-truth")
      o.ground_truth = true;
    else
      return make_error("euroc sink: ", opt,
                        ": unknown option (expected no-augmented, no-masks, no-plot or ground-truth)");
  }
  return make_euroc_sink(dir, o, setup, nullptr);
}

}  // namespace augrig::pipeline
