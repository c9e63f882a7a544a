// stats.csv as a sink: one row per augmented pair, flushed per row (outputs.hpp's StatsCsvWriter).
#include "pipeline/sinks/sinks.hpp"

namespace augrig::pipeline {

namespace {

class StatsSink final : public FrameSink {
 public:
  explicit StatsSink(std::unique_ptr<StatsCsvWriter> writer) : writer_(std::move(writer)) {}
  Status consume(PairContext& pair) override {
    return pair.result ? writer_->add(pair.result->stats) : Status{};
  }

 private:
  std::unique_ptr<StatsCsvWriter> writer_;
};

}  // namespace

std::unique_ptr<FrameSink> make_stats_sink(std::unique_ptr<StatsCsvWriter> writer) {
  return std::make_unique<StatsSink>(std::move(writer));
}

}  // namespace augrig::pipeline
