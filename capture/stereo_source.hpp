// StereoSource: the capture and pairing stages of the live pipeline. Each FrameSource is read on
// a thread of its own, so a camera never waits for the other camera or for what comes downstream;
// frames cross to the pairer through a bounded queue per source, and pairs come out of read().
//
// Live sources (cameras) never block: when a queue is full its oldest frame is dropped and counted.
// Finite sources (replay, simulation) run lockstep instead (`lossless`): capture waits for room,
// so nothing is dropped however slow the consumer is. Every frame is accounted for: delivered in
// a pair, dropped by the camera or transport (the source's own counts), by a full queue, by the
// pairer (with its reason), or still pending.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "capture/stereo_pairer.hpp"
#include "core/expected.hpp"
#include "core/frame.hpp"

namespace augrig {

struct StereoSourceOptions {
  StereoPairerConfig pairing;
  std::size_t queue_frames = 8;  // per source, between its capture thread and the pairer
  bool lossless = false;         // capture waits for room instead of dropping (finite sources)
  std::chrono::nanoseconds read_timeout = std::chrono::milliseconds(100);  // per source read()
  // A source's read() error skips that frame instead of ending the source (a recording's damaged
  // frame: the source counts it in frames_dropped() and goes on). The errors are kept for
  // take_errors().
  bool skip_read_errors = false;
};

struct StereoSourceStats {
  std::uint64_t frames[2] = {0, 0};       // read from the sources, per camera
  std::uint64_t queue_drops[2] = {0, 0};  // dropped because the pairer's queue was full
  TimeSpan queue_drop_t;                  // their t_ns, both cameras
  // Frames read but not (yet) paired, dropped or returned: in the capture queues, waiting in the
  // pairer for a partner, or paired and not yet read (two per pair). After stop() these are the
  // frames a stopped run never got to: frames = 2 pairs read + unpaired + queue drops + pending.
  TimeSpan pending;
  std::uint64_t camera_drops = 0;  // the sources' own counts (SourceHealth)
  std::uint64_t transport_drops = 0;
  PairerStats pairing;
  std::vector<ClockOffsetLog> clocks;  // the latest clock offset estimate per camera, if estimated
};

class StereoSource {
 public:
  // One source delivering both cameras (sim://, replay://) or two (left, right: each frame's camera
  // is set by its source's position). Starts the capture threads.
  static Expected<std::unique_ptr<StereoSource>> create(std::vector<std::unique_ptr<FrameSource>> sources,
                                                        const StereoSourceOptions& options);
  ~StereoSource();  // stop()
  StereoSource(const StereoSource&) = delete;
  StereoSource& operator=(const StereoSource&) = delete;

  // The next stereo frame. kEndOfStream once every source ended and nothing pairs any more; an
  // Error when a source failed (its message names it).
  Expected<ReadStatus> read(StereoFrame& out, std::chrono::nanoseconds timeout);
  // Ends the capture threads. What they had queued stays: read() with a zero timeout still returns
  // the pairs it makes (then kTimeout), and stats() counts the rest as pending.
  void stop();
  bool lossless() const;  // StereoSourceOptions::lossless: capture waits for room (finite sources)

  std::string uri() const;
  StereoSourceStats stats() const;
  std::vector<SourceHealth> health() const;  // per source
  // The read errors skipped since the last call (skip_read_errors), oldest first, at most 100.
  std::vector<std::string> take_errors();
  // The sources, e.g. to reach a camera's own statistics. Their read() belongs to the threads.
  const std::vector<std::unique_ptr<FrameSource>>& sources() const;

 private:
  struct Impl;
  explicit StereoSource(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace augrig
