// Recorder: writes a recording (docs/RECORDING.md) while the pipeline runs, without ever holding
// it up.
//
//   auto rec = recorder::Recorder::create("flight-042", info, options);   // DIR/recording.sqlite
//   rec->push(std::move(frame_record));   // never blocks; false: dropped (and entered in the ledger)
//   rec->push(recorder::imu_input(sample));
//   ...
//   Status st = rec->close();             // flushes, writes the summary
//
// Threads: push() puts the item into a bounded queue and returns. `compression_threads` workers
// encode frames (recorder/codec.hpp); one writer thread inserts them in push order and commits a
// transaction at least every `commit_interval`; one checkpointer thread copies the WAL into the
// database every `checkpoint_interval` (PASSIVE checkpoints, which do not block the writer; the
// writer copies the last few frames between two transactions so that SQLite can start the WAL
// over instead of letting it grow for the whole recording).
//
// What survives what (synchronous=NORMAL in WAL mode):
//   - the process is killed (kill -9, a crash): every committed transaction is in the WAL file, so
//     the recording holds every frame pushed more than commit_interval + the write time before,
//     as long as the writer kept up (frames still queued are lost);
//   - power loss or an OS crash: the WAL is fsynced only by checkpoints, so what is certain is
//     what the last completed checkpoint held (at most checkpoint_interval + its duration old);
//     the database is consistent either way.
//
// Errors: disk full, an I/O error, the size cap (`max_bytes`), or a file size limit (RLIMIT_FSIZE;
// create() sets SIGXFSZ to ignored when it is at its default, so write() fails with EFBIG instead
// of killing the process) stop the recording. The transaction in progress rolls back, the
// database stays valid with everything committed before, status() returns the error, and push()
// keeps returning false at once, counting every item as dropped (stage recorder).
//
// push() and the accessors may be called from any thread; create() and close() from one.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>

#include "core/expected.hpp"
#include "recorder/record.hpp"

namespace augrig::recorder {

struct RecorderOptions {
  // Frames inside the recorder (queued, being compressed, or waiting to be written) at most;
  // a frame pushed beyond this is dropped. Nav inputs, events and look updates have their own bound.
  std::size_t queue_capacity = 64;
  std::size_t small_queue_capacity = 1 << 16;  // nav inputs, events and look updates
  std::chrono::milliseconds commit_interval{250};
  std::chrono::milliseconds checkpoint_interval{1000};
  int zstd_level = 1;           // 1..3 keep up with 1280x960 stereo at well over 100 fps on 2 cores
  int compression_threads = 2;  // at least 1
  // Cap on the database size (PRAGMA max_page_count); 0: none. Reaching it stops the recording
  // like a full disk does.
  std::int64_t max_bytes = 0;
  bool overwrite = false;  // replace an existing DIR/recording.sqlite instead of failing
  // Tests: the writer sleeps this long before writing each frame (a slow disk).
  std::chrono::microseconds writer_delay_for_testing{0};
};

// Counters since create(); consistent with each other only after close().
struct RecorderStats {
  std::uint64_t frames_pushed = 0;     // accepted by push()
  std::uint64_t frames_written = 0;    // inserted (committed or in the open transaction)
  std::uint64_t frames_committed = 0;  // in a committed transaction
  std::uint64_t frames_dropped = 0;    // by the recorder (queue full, stopped, invalid, rolled back)
  std::uint64_t frames_in_flight = 0;  // accepted, not yet written or dropped
  std::uint64_t nav_inputs_committed = 0;
  std::uint64_t events_committed = 0;
  std::uint64_t look_updates_committed = 0;  // LookRecords
  std::uint64_t small_items_dropped = 0;     // nav inputs, events and look updates dropped by the recorder
  std::uint64_t commits = 0;
  std::uint64_t checkpoints = 0;
  std::uint64_t image_bytes = 0;   // uncompressed bytes of the images of written frames
  std::uint64_t stored_bytes = 0;  // their blobs' bytes
  // Raw images of committed frames stored by copying their replayed blob (push()), not compressed.
  std::uint64_t raw_blobs_copied = 0;
  // Cost per stage, summed over frames, milliseconds.
  double encode_ms = 0;      // CPU time of predictor + zstd of raw, augmented and masks (all workers)
  double insert_ms = 0;      // CPU time of the SQLite INSERTs of the frame rows
  double commit_ms = 0;      // wall time of the COMMITs
  double checkpoint_ms = 0;  // wall time of the WAL checkpoints (mostly the checkpointer's, fsync included)
};

class Recorder {
 public:
  // Creates DIR (and parents) and DIR/recording.sqlite with the schema and `info` in `meta`,
  // and starts the threads. Fails when the database exists (unless options.overwrite) or cannot
  // be created; the error names the file.
  static Expected<std::unique_ptr<Recorder>> create(const std::string& dir, const RecordingInfo& info,
                                                    const RecorderOptions& options = {});
  ~Recorder();  // close(), its result ignored
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  // Never blocks on I/O (a short mutex only). Frames: false when the frame was dropped (queue full,
  // recording stopped, invalid: augmented, mask or receiver depth size differing from the raw image,
  // an augmented box outside it); the drop is counted in the ledger. DropRecords are merged into the ledger.
  // After close(): false.
  // A raw image is stored by copying its blob from the recording it was replayed from, without
  // decoding or compressing (counted in RecorderStats::raw_blobs_copied), when its Frame's
  // `attachment` is a recorder::RecordedFrame (replay_source.hpp; ReplaySource attaches one when
  // ReplayOptions::keep_raw_blobs is on, the default) whose raw_blobs[c] for that camera position
  // (0 left, 1 right) is not empty and has the image's format, width, height and the Frame's t_ns,
  // and whose fingerprint equals raw_fingerprint() (codec.hpp) of the image. Otherwise it is
  // compressed as usual. Either way the image reads back the same.
  bool push(RecordItem&& item);

  // OK while recording; the error that stopped the recording otherwise.
  Status status() const;
  RecorderStats stats() const;
  const std::string& path() const;  // DIR/recording.sqlite

  // Writes everything queued, the drop ledger and the summary (meta "summary.*"), checkpoints the
  // WAL into the database and closes it. Returns the error that stopped the recording, if one did.
  // A second call returns the first call's result.
  Status close();

 private:
  struct Impl;
  explicit Recorder(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace augrig::recorder
