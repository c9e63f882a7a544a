// The per-frame files as a sink: every `every`-th augmented pair's images (augmented, masks,
// visualisations) and, asked for, its ground truth, named by the command's rule or by the pair
// (a replayed recording's: its recorded index, and the loop pass after the first).
#include <iomanip>
#include <sstream>

#include "pipeline/sinks/sinks.hpp"

namespace augrig::pipeline {

namespace {

class FrameFilesSink final : public FrameSink {
 public:
  FrameFilesSink(FrameFiles files, const Rig& rig) : files_(std::move(files)), rig_(rig) {}

  Status consume(PairContext& pair) override {
    if (!pair.result || (pair.pair - 1) % static_cast<std::uint64_t>(files_.every) != 0) return {};
    const FrameNames names = files_.names ? files_.names(pair.raw) : names_of(pair);
    if (Status st = write_frame_images(files_.dir, names, pair.raw, *pair.result); !st) return st;
    if (files_.ground_truth) return write_ground_truth(files_.dir, names, *pair.result, rig_);
    return {};
  }

 private:
  static FrameNames names_of(const PairContext& pair) {
    const std::optional<SourcePosition>& at = pair.position;
    std::ostringstream stem;
    if (at && at->pass) stem << "pass" << at->pass << "_";
    stem << std::setw(6) << std::setfill('0') << (at ? at->index : pair.raw.pair_sequence);
    return {stem.str(), stem.str()};
  }

  FrameFiles files_;
  const Rig& rig_;
};

}  // namespace

std::unique_ptr<FrameSink> make_frame_files_sink(FrameFiles files, const Rig& rig) {
  return std::make_unique<FrameFilesSink>(std::move(files), rig);
}

}  // namespace augrig::pipeline
