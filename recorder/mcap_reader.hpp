// McapReader: reads an MCAP file (https://mcap.dev/spec) back, checking it as it goes: the magic
// at both ends, the footer, the summary's CRC, every record's length against the bytes left, every
// chunk's size and CRC after zstd. Written against the public specification, like McapWriter.
//
//   auto r = McapReader::open("out.mcap");          // the summary: schemas, channels, statistics, indexes
//   McapMessage m;
//   while (true) {
//     auto more = (*r)->next(m);                     // messages in file order, chunk by chunk
//     if (!more) ... more.error() names the file, the offset and the record
//     if (!*more) break;                             // Data End
//   }
//
// Only one chunk is held in memory at a time. Damage is an Error naming the file and the offset of
// the record (and, inside a chunk, the offset within the uncompressed chunk); never a crash, never
// an allocation larger than the file says and the bytes left allow. Not thread-safe.
#pragma once

#include <cstdint>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/expected.hpp"

namespace augrig::recorder {

struct McapSchemaInfo {
  std::uint16_t id = 0;
  std::string name, encoding, data;
};
struct McapChannelInfo {
  std::uint16_t id = 0, schema_id = 0;
  std::string topic, message_encoding;
  std::map<std::string, std::string> metadata;
};
struct McapMessage {
  std::uint16_t channel_id = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time_ns = 0, publish_time_ns = 0;
  std::vector<std::uint8_t> data;
};
struct McapStatistics {
  std::uint64_t message_count = 0;
  std::uint16_t schema_count = 0;
  std::uint32_t channel_count = 0, attachment_count = 0, metadata_count = 0, chunk_count = 0;
  std::uint64_t message_start_ns = 0, message_end_ns = 0;
  std::map<std::uint16_t, std::uint64_t> channel_message_counts;
};
struct McapChunkIndex {
  std::uint64_t message_start_ns = 0, message_end_ns = 0;
  std::uint64_t chunk_offset = 0, chunk_length = 0;
  std::map<std::uint16_t, std::uint64_t> message_index_offsets;
  std::uint64_t message_index_length = 0;
  std::string compression;
  std::uint64_t compressed_size = 0, uncompressed_size = 0;
};
struct McapSummary {
  std::string profile, library;  // the Header
  std::map<std::uint16_t, McapSchemaInfo> schemas;
  std::map<std::uint16_t, McapChannelInfo> channels;
  std::optional<McapStatistics> statistics;
  std::vector<McapChunkIndex> chunk_indexes;
  std::map<std::string, std::uint64_t> metadata_offsets;  // Metadata Index: name -> record offset
  std::uint64_t summary_start = 0, summary_offset_start = 0;
};

class McapReader {
 public:
  static Expected<std::unique_ptr<McapReader>> open(const std::string& path);
  ~McapReader();
  McapReader(const McapReader&) = delete;
  McapReader& operator=(const McapReader&) = delete;

  const std::string& path() const { return path_; }
  std::uint64_t file_size() const { return size_; }
  const McapSummary& summary() const { return summary_; }
  // The channels and schemas met so far while streaming (the data section's own copies), merged
  // with the summary's.
  const std::map<std::uint16_t, McapChannelInfo>& channels() const { return channels_; }
  const std::map<std::uint16_t, McapSchemaInfo>& schemas() const { return schemas_; }
  // The topic's channel id, or 0.
  std::uint16_t channel_id(const std::string& topic) const;

  // The Metadata record named `name` (through the summary's Metadata Index); nullopt when absent.
  Expected<std::optional<std::map<std::string, std::string>>> metadata(const std::string& name);

  // The next message in file order: true, or false at Data End.
  Expected<bool> next(McapMessage& out);
  // Back to the first record of the data section.
  void rewind();

 private:
  McapReader() = default;
  Status read_at(std::uint64_t offset, std::uint64_t n, std::vector<std::uint8_t>& out);
  Error error_at(std::uint64_t offset, const std::string& what) const;

  std::string path_;
  std::ifstream in_;
  std::uint64_t size_ = 0;
  std::uint64_t data_start_ = 0, data_end_ = 0;  // the data section's records: [start, end)
  McapSummary summary_;
  std::map<std::uint16_t, McapChannelInfo> channels_;
  std::map<std::uint16_t, McapSchemaInfo> schemas_;

  // Streaming position: the next record at pos_, or inside the current chunk.
  std::uint64_t pos_ = 0;
  bool done_ = false;
  std::vector<std::uint8_t> chunk_;  // the current chunk's records, uncompressed
  std::size_t chunk_pos_ = 0;
  std::uint64_t chunk_offset_ = 0;  // the chunk record's offset in the file
  std::vector<std::uint8_t> record_, compressed_;
};

}  // namespace augrig::recorder
