// RecordingReader: reads a recording (docs/RECORDING.md) back, bit-exact, and checks it.
//
//   auto rec = recorder::RecordingReader::open("flight-042");   // or the .sqlite file
//   for (std::size_t i = 0; i < (*rec)->frame_count(); ++i) {
//     auto f = (*rec)->read_frame(i);   // an error names the file, the frame and the blob
//     ...
//   }
//   recorder::CheckReport report = (*rec)->check();
//
// Damage stays local: open() fails only when the file is not a readable recording at all (no
// such file, not SQLite, no meta table, a newer schema), with an error naming the file. A frame
// whose row or blob is damaged fails in read_frame() for that frame alone; when the table itself
// is damaged, the frames before the damage are listed and the damage is in problems().
//
// A recording still being written can be read (SQLite WAL readers see the last commit at open).
// The reader opens the database read-write when it may, so that SQLite can recover the WAL of a
// recording whose writer was killed, and sets query_only: it never changes the recorded data.
// Not thread-safe: one reader per thread.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/expected.hpp"
#include "recorder/record.hpp"

namespace augrig::recorder {

// What a recording holds and what is wrong with it (RecordingReader::check()).
struct CheckReport {
  std::string path;
  int schema_version = 0;
  std::string software;
  bool closed_cleanly = false;  // the Recorder wrote its summary (false after a crash)
  std::string summary_status;   // "ok", or the error that stopped the recording
  std::size_t frames = 0;
  std::size_t frames_ok = 0;  // every blob decoded and every size matched
  std::size_t frames_augmented = 0;
  std::size_t frames_with_masks = 0;
  std::size_t frames_with_depth = 0;  // receiver depth recorded (--ground-truth)
  std::size_t frames_with_stats = 0;
  TimestampNs t_first_ns = 0, t_last_ns = 0;  // frames' t_ns
  // "left: BayerRG8 1280x960, clock device" -> frames
  std::map<std::string, std::size_t> cameras;
  std::map<std::string, std::uint64_t> drops_by_stage;  // summed counts, every stage listed
  std::map<std::string, std::size_t> nav_inputs_by_stream;
  std::size_t events = 0;
  // Rows of the `look` table (schema 3): noise level functions and light fits recorded.
  std::size_t look_noise = 0, look_light = 0;
  std::uint64_t image_bytes = 0;      // uncompressed images of the frames read
  std::uint64_t stored_bytes = 0;     // their blobs
  std::vector<std::string> problems;  // empty: everything decoded and matched

  bool ok() const { return problems.empty(); }
  // Printable summary, one fact per line.
  std::string to_string() const;
};

class RecordingReader {
 public:
  // `dir_or_file`: the recording folder or its recording.sqlite.
  static Expected<std::unique_ptr<RecordingReader>> open(const std::string& dir_or_file);
  ~RecordingReader();
  RecordingReader(const RecordingReader&) = delete;
  RecordingReader& operator=(const RecordingReader&) = delete;

  const std::string& path() const;
  int schema_version() const;
  const std::map<std::string, std::string>& meta() const;
  // The meta value, or "" when absent.
  std::string meta(const std::string& key) const;

  std::size_t frame_count() const;
  // Frame i (0 <= i < frame_count(), in recording order). `parts`: FrameParts bits of what to
  // decode (record.hpp); metadata, poses and stats always. Images not asked for stay empty.
  Expected<FrameRecord> read_frame(std::size_t i, unsigned parts = kPartsAll) const;
  // The same, and with `raw_blobs` set, each camera's raw blob as stored, for a Recorder to copy
  // (record.hpp, StoredRawBlob): its bytes, the image's size, format and t_ns, and with kPartRaw
  // the decoded image's raw_fingerprint(). A blob's bytes stay empty when the recording's raw
  // encoding (meta `codec.raw`) is not this build's.
  Expected<FrameRecord> read_frame(std::size_t i, unsigned parts, std::array<StoredRawBlob, 2>* raw_blobs) const;
  // Whether frame i holds both cameras' receiver depth (FrameRecord::receiver_depth), without
  // decoding it: false for a recording made without --ground-truth (and every schema 1 recording).
  bool has_depth(std::size_t i) const;
  // Frame i's metadata only (no blob is read): raw images empty, everything else filled.
  Expected<FrameRecord> read_frame_info(std::size_t i) const { return read_frame(i, kPartsNone); }

  // All nav inputs in recording order, or those of one stream.
  Expected<std::vector<NavInputRecord>> nav_inputs(
      const std::optional<std::string>& stream = std::nullopt) const;
  Expected<std::vector<DropRecord>> drops() const;
  Expected<std::vector<EventRecord>> events() const;
  // The camera look's updates in recording order (empty for a recording made before schema 3, or
  // with the plain look). An error names the file, the row and the column.
  Expected<std::vector<LookRecord>> look() const;

  // Damage found while opening (an unreadable part of the frames table), for check().
  const std::vector<std::string>& problems() const;

  // Reads every frame and decodes every blob (sizes, zstd checksums), runs SQLite's quick_check,
  // and summarises the tables. Never fails: what cannot be read is a problem in the report.
  CheckReport check() const;

 private:
  struct Impl;
  explicit RecordingReader(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace augrig::recorder
