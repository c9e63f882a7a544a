// McapWriter: writes an MCAP file (https://mcap.dev/spec, major version 0), written here against
// the public specification: magic, Header, a data section of zstd-compressed Chunks (each followed
// by one Message Index per channel it holds), Metadata records, Data End with the data section's
// CRC32, a summary section grouped by opcode (Schemas, Channels, Statistics, Metadata Indexes,
// Chunk Indexes), Summary Offsets, Footer with the summary CRC32, magic.
//
//   auto w = McapWriter::create("out.mcap", {});
//   const auto schema = (*w)->add_schema("sensor_msgs/msg/Image", "ros2msg", text);
//   const auto channel = (*w)->add_channel(schema, "/left/image_raw", "cdr", {});
//   (*w)->write_message(channel, log_time_ns, bytes);   // ... then
//   (*w)->close();                                       // the summary and the footer
//
// A Schema and its Channel are written into the chunk that holds the channel's first message, so a
// streaming reader meets them before the message; the summary repeats them for indexed readers.
// Messages should come in log_time order (readers merge chunks by time; we never reorder).
// Not thread-safe. Errors name the file.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/expected.hpp"

namespace augrig::recorder {

// The opcodes of the MCAP records (specification, "Records").
enum class McapOp : std::uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kAttachment = 0x09,
  kAttachmentIndex = 0x0A,
  kStatistics = 0x0B,
  kMetadata = 0x0C,
  kMetadataIndex = 0x0D,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F,
};

// 0x89 'M' 'C' 'A' 'P' '0' '\r' '\n': at the start and at the end of every MCAP file.
inline constexpr std::uint8_t kMcapMagic[8] = {0x89, 'M', 'C', 'A', 'P', 0x30, '\r', '\n'};

struct McapWriterOptions {
  std::string profile = "ros2";   // Header.profile
  std::string library = "augrig";  // Header.library
  // A chunk is closed once its uncompressed records reach this size (one image may exceed it).
  std::size_t chunk_size_bytes = 4u << 20;
  int zstd_level = 3;
};

struct McapWriterStats {
  std::uint64_t messages = 0, chunks = 0, bytes_written = 0;
  std::uint64_t uncompressed_bytes = 0, compressed_bytes = 0;  // chunk records, before and after zstd
};

class McapWriter {
 public:
  // Creates (truncates) `path` and writes the magic and the Header.
  static Expected<std::unique_ptr<McapWriter>> create(const std::string& path, const McapWriterOptions& options);
  ~McapWriter();  // closes the file without a summary if close() was not called (a truncated file)
  McapWriter(const McapWriter&) = delete;
  McapWriter& operator=(const McapWriter&) = delete;

  // Ids count from 1. `data` is the schema text (ros2msg: the concatenated .msg definitions).
  std::uint16_t add_schema(const std::string& name, const std::string& encoding, const std::string& data);
  std::uint16_t add_channel(std::uint16_t schema_id, const std::string& topic, const std::string& message_encoding,
                            const std::map<std::string, std::string>& metadata);
  // publish_time = log_time; `sequence` is the channel's message counter (set by the writer).
  Status write_message(std::uint16_t channel_id, std::uint64_t log_time_ns, const std::uint8_t* data, std::size_t n);
  Status write_message(std::uint16_t channel_id, std::uint64_t log_time_ns, const std::vector<std::uint8_t>& data) {
    return write_message(channel_id, log_time_ns, data.data(), data.size());
  }
  // A Metadata record (outside any chunk) and its index in the summary.
  Status write_metadata(const std::string& name, const std::map<std::string, std::string>& metadata);
  // Flushes the last chunk, writes Data End, the summary, the summary offsets, the footer and the
  // magic, and closes the file.
  Status close();

  const McapWriterStats& stats() const { return stats_; }
  const std::string& path() const { return path_; }

 private:
  McapWriter() = default;
  struct Impl;
  Status flush_chunk();
  Status write_raw(const std::uint8_t* data, std::size_t n);
  Status fail(const std::string& what);

  std::string path_;
  McapWriterStats stats_;
  std::unique_ptr<Impl> impl_;
};

// CRC-32 (ISO-HDLC, as zlib and MCAP compute it) of `n` bytes continuing from `crc` (0 to start).
std::uint32_t mcap_crc32(std::uint32_t crc, const std::uint8_t* data, std::size_t n);

}  // namespace augrig::recorder
