// The window's mailbox as a sink (pipeline/live_view.hpp): each augmented pair made whole and
// handed over by swap (the pipeline gets the previous pair's buffers back for the next), or,
// captured only, a copy of the raw pair (nothing is overlaid). A paused live run goes on
// processing and recording while the window keeps its frozen pair; a paused replay only steps,
// and each step is shown.
#include "pipeline/report.hpp"
#include "pipeline/sinks/sinks.hpp"

namespace augrig::pipeline {

namespace {

class ViewSink final : public FrameSink {
 public:
  explicit ViewSink(std::shared_ptr<LiveView> view) : view_(std::move(view)) {}
  SinkNeeds needs() const override { return {.whole_images = true}; }

  Status consume(PairContext& pair) override {
    // A paused replay's steps are shown (made whole too); a paused live run's pairs are not.
    if (pair.result) {
      if (!pair.paused || pair.replay) pair.make_whole();
      return {};
    }
    if (pair.paused) return {};
    // Captured only: copied now, before the recorder takes the raw frame.
    for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
      ViewResult& v = id == CameraId::kLeft ? raw_.left : raw_.right;
      v.augmented = Image::copy_of(pair.raw[id].image.cview());
      v.mask = Image();
    }
    return {};
  }

  void release(PairContext& pair) override {
    if (pair.result) {
      if (!pair.paused || pair.replay) view_->publish(*pair.result, *pair.scene, pair.mid_host_ns);
    } else if (!pair.paused) {
      view_->publish(
          raw_, pair.scene ? *pair.scene : SceneState{BoomArticulation{}, Pose::identity(), false, {}, {}},
          pair.mid_host_ns);
    }
  }

  Status close(PipelineReport& report) override {
    view_->finish();
    report.display_latency = view_->display_histogram();
    return {};
  }

 private:
  std::shared_ptr<LiveView> view_;
  StereoResult raw_;  // captured only: the raw pair's copy, swapped with the window's
};

}  // namespace

std::unique_ptr<FrameSink> make_view_sink(std::shared_ptr<LiveView> view) {
  return std::make_unique<ViewSink>(std::move(view));
}

}  // namespace augrig::pipeline
