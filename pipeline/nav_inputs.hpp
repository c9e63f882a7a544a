// The run's live nav inputs: "STREAM=URI,..." opened, each read on its own thread, each unit of
// input pushed to the recorder as received (NavInputRecord: text lines and gpsd reports as TEXT,
// IMU datagrams as BLOB), the parsed events counted and, for streams of an aircraft (tanker.*,
// receiver.*), fed to the live fusion.
#pragma once

#include <atomic>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "core/expected.hpp"
#include "nav/live_input.hpp"
#include "pipeline/live_nav.hpp"
#include "recorder/recorder.hpp"

namespace augrig::pipeline {

// "NAME=VALUE,..." split; an item without '=' or without a name is an Error naming it.
Expected<std::vector<std::pair<std::string, std::string>>> parse_named_list(const std::string& spec,
                                                                            const std::string& what);

class NavInputs {
 public:
  NavInputs() = default;
  NavInputs(const NavInputs&) = delete;
  NavInputs& operator=(const NavInputs&) = delete;
  ~NavInputs() { stop(); }

  // Opens every input (an Error names the first that fails) and starts its thread; `rec` and
  // `live_nav` may be null.
  Status open(const std::vector<std::pair<std::string, std::string>>& items, recorder::Recorder* rec,
              LiveNav* live_nav);
  // The UDP port a stream's input is bound to (0: not a UDP input).
  std::uint16_t port(const std::string& stream) const;
  void stop();
  bool empty() const { return inputs_.empty(); }
  // One line per input: counts, losses, the last problem.
  void summary(std::ostream& out) const;
  // The inputs' losses as drop-ledger rows.
  void ledger(recorder::Recorder& rec) const;

 private:
  struct Input {
    std::string stream;
    std::optional<Aircraft> aircraft;
    std::unique_ptr<nav::NavInput> input;
    std::thread thread;
    std::uint64_t fixes = 0, imu = 0, baselines = 0;
    std::string error;
  };
  std::deque<Input> inputs_;  // stable addresses for the threads
  std::atomic<bool> stop_{false};
};

}  // namespace augrig::pipeline
