// A command's own per-pair output as a sink (evaluate's matchers, the demo's files): called for
// every augmented pair with the changed boxes as made; its Error ends the run.
#include "pipeline/sinks/sinks.hpp"

namespace augrig::pipeline {

namespace {

class CallbackSink final : public FrameSink {
 public:
  explicit CallbackSink(PairCallback on_pair) : on_pair_(std::move(on_pair)) {}
  Status consume(PairContext& pair) override {
    if (!pair.result || !pair.scene) return {};
    return on_pair_(pair.raw, *pair.result, *pair.scene, pair.poses);
  }

 private:
  PairCallback on_pair_;
};

}  // namespace

std::unique_ptr<FrameSink> make_callback_sink(PairCallback on_pair) {
  return std::make_unique<CallbackSink>(std::move(on_pair));
}

}  // namespace augrig::pipeline
