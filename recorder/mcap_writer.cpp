// McapWriter (mcap_writer.hpp): the records of the MCAP specification, serialised little-endian,
// chunks compressed with zstd.
#include "recorder/mcap_writer.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <limits>
#include <set>

#include <zlib.h>
#include <zstd.h>

namespace augrig::recorder {

std::uint32_t mcap_crc32(std::uint32_t crc, const std::uint8_t* data, std::size_t n) {
  // zlib's crc32 takes uInt lengths: feed it in pieces below 4 GiB.
  uLong c = crc;
  while (n > 0) {
    const std::size_t piece = std::min<std::size_t>(n, 1u << 30);
    c = ::crc32(c, data, static_cast<uInt>(piece));
    data += piece;
    n -= piece;
  }
  return static_cast<std::uint32_t>(c);
}

namespace {

// A record's content, built field by field in the specification's serialisation.
struct Bytes {
  std::vector<std::uint8_t> b;
  void u8(std::uint8_t v) { b.push_back(v); }
  void u16(std::uint16_t v) { le(v, 2); }
  void u32(std::uint32_t v) { le(v, 4); }
  void u64(std::uint64_t v) { le(v, 8); }
  void le(std::uint64_t v, int n) {
    for (int i = 0; i < n; ++i) b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  void str(const std::string& s) {
    u32(static_cast<std::uint32_t>(s.size()));
    b.insert(b.end(), s.begin(), s.end());
  }
  void raw(const void* p, std::size_t n) {
    const auto* c = static_cast<const std::uint8_t*>(p);
    b.insert(b.end(), c, c + n);
  }
  void string_map(const std::map<std::string, std::string>& m) {
    Bytes e;
    for (const auto& [k, v] : m) {
      e.str(k);
      e.str(v);
    }
    u32(static_cast<std::uint32_t>(e.b.size()));
    raw(e.b.data(), e.b.size());
  }
  void u16_u64_map(const std::map<std::uint16_t, std::uint64_t>& m) {
    u32(static_cast<std::uint32_t>(m.size() * 10));
    for (const auto& [k, v] : m) {
      u16(k);
      u64(v);
    }
  }
  // <opcode><uint64 length><content> appended to `out`.
  void record_into(McapOp op, std::vector<std::uint8_t>& out) const {
    out.push_back(static_cast<std::uint8_t>(op));
    for (int i = 0; i < 8; ++i) out.push_back(static_cast<std::uint8_t>(static_cast<std::uint64_t>(b.size()) >> (8 * i)));
    out.insert(out.end(), b.begin(), b.end());
  }
};

struct Schema {
  std::uint16_t id;
  std::string name, encoding, data;
};
struct Channel {
  std::uint16_t id, schema_id;
  std::string topic, encoding;
  std::map<std::string, std::string> metadata;
};

Bytes schema_record(const Schema& s) {
  Bytes r;
  r.u16(s.id);
  r.str(s.name);
  r.str(s.encoding);
  r.str(s.data);  // uint32 length-prefixed bytes: the same layout as a String
  return r;
}
Bytes channel_record(const Channel& c) {
  Bytes r;
  r.u16(c.id);
  r.u16(c.schema_id);
  r.str(c.topic);
  r.str(c.encoding);
  r.string_map(c.metadata);
  return r;
}

}  // namespace

struct McapWriter::Impl {
  std::FILE* file = nullptr;
  McapWriterOptions options;
  ZSTD_CCtx* cctx = nullptr;
  bool closed = false;
  bool failed = false;
  std::uint64_t offset = 0;         // bytes written so far
  std::uint32_t data_crc = 0;       // of everything written before Data End

  std::vector<Schema> schemas;      // id = index + 1
  std::vector<Channel> channels;    // id = index + 1
  std::set<std::uint16_t> schemas_written, channels_written;  // into the data section
  std::map<std::uint16_t, std::uint64_t> channel_counts;
  std::map<std::uint16_t, std::uint32_t> sequences;

  // The open chunk.
  std::vector<std::uint8_t> chunk;  // uncompressed records
  std::uint64_t chunk_start = 0, chunk_end = 0;
  bool chunk_has_messages = false;
  std::map<std::uint16_t, std::vector<std::pair<std::uint64_t, std::uint64_t>>> chunk_index;  // log_time, offset
  std::vector<std::uint8_t> compressed;

  // The summary's records.
  std::vector<Bytes> chunk_indexes, metadata_indexes;
  std::uint64_t message_start = 0, message_end = 0;
  std::uint32_t metadata_count = 0;
};

Expected<std::unique_ptr<McapWriter>> McapWriter::create(const std::string& path, const McapWriterOptions& options) {
  std::unique_ptr<McapWriter> w(new McapWriter());
  w->path_ = path;
  w->impl_ = std::make_unique<Impl>();
  Impl& m = *w->impl_;
  m.options = options;
  m.file = std::fopen(path.c_str(), "wb");
  if (!m.file)
    return Error{"recorder::McapWriter::create(): " + path + ": cannot create the file: " + std::strerror(errno)};
  m.cctx = ZSTD_createCCtx();
  if (!m.cctx) return Error{"recorder::McapWriter::create(): " + path + ": cannot create a zstd context"};
  ZSTD_CCtx_setParameter(m.cctx, ZSTD_c_compressionLevel, options.zstd_level);
  ZSTD_CCtx_setParameter(m.cctx, ZSTD_c_contentSizeFlag, 1);
  if (Status s = w->write_raw(kMcapMagic, sizeof kMcapMagic); !s) return s.error();
  Bytes header;
  header.str(options.profile);
  header.str(options.library);
  std::vector<std::uint8_t> rec;
  header.record_into(McapOp::kHeader, rec);
  if (Status s = w->write_raw(rec.data(), rec.size()); !s) return s.error();
  return w;
}

McapWriter::~McapWriter() {
  if (!impl_) return;
  if (impl_->file) std::fclose(impl_->file);
  if (impl_->cctx) ZSTD_freeCCtx(impl_->cctx);
}

Status McapWriter::fail(const std::string& what) {
  impl_->failed = true;
  return Error{"recorder::McapWriter: " + path_ + ": " + what};
}

Status McapWriter::write_raw(const std::uint8_t* data, std::size_t n) {
  Impl& m = *impl_;
  if (n && std::fwrite(data, 1, n, m.file) != n) return fail(std::string("cannot write: ") + std::strerror(errno));
  m.offset += n;
  stats_.bytes_written = m.offset;
  return {};
}

std::uint16_t McapWriter::add_schema(const std::string& name, const std::string& encoding, const std::string& data) {
  Impl& m = *impl_;
  const auto id = static_cast<std::uint16_t>(m.schemas.size() + 1);
  m.schemas.push_back({id, name, encoding, data});
  return id;
}

std::uint16_t McapWriter::add_channel(std::uint16_t schema_id, const std::string& topic,
                                      const std::string& message_encoding,
                                      const std::map<std::string, std::string>& metadata) {
  Impl& m = *impl_;
  const auto id = static_cast<std::uint16_t>(m.channels.size() + 1);
  m.channels.push_back({id, schema_id, topic, message_encoding, metadata});
  return id;
}

Status McapWriter::write_message(std::uint16_t channel_id, std::uint64_t log_time_ns, const std::uint8_t* data,
                                 std::size_t n) {
  Impl& m = *impl_;
  if (m.closed || m.failed) return fail("write_message() after close() or a failed write");
  if (channel_id == 0 || channel_id > m.channels.size())
    return fail("write_message(): no channel " + std::to_string(channel_id));
  const Channel& c = m.channels[channel_id - 1u];
  // The schema and the channel go into the data section before their first message.
  if (c.schema_id && !m.schemas_written.count(c.schema_id)) {
    schema_record(m.schemas.at(c.schema_id - 1u)).record_into(McapOp::kSchema, m.chunk);
    m.schemas_written.insert(c.schema_id);
  }
  if (!m.channels_written.count(channel_id)) {
    channel_record(c).record_into(McapOp::kChannel, m.chunk);
    m.channels_written.insert(channel_id);
  }
  m.chunk_index[channel_id].emplace_back(log_time_ns, m.chunk.size());
  Bytes msg;
  msg.b.reserve(22 + n);
  msg.u16(channel_id);
  msg.u32(m.sequences[channel_id]++);
  msg.u64(log_time_ns);
  msg.u64(log_time_ns);  // publish_time: not known apart from the log time
  msg.raw(data, n);
  msg.record_into(McapOp::kMessage, m.chunk);
  if (!m.chunk_has_messages) {
    m.chunk_start = m.chunk_end = log_time_ns;
    m.chunk_has_messages = true;
  }
  m.chunk_start = std::min(m.chunk_start, log_time_ns);
  m.chunk_end = std::max(m.chunk_end, log_time_ns);
  if (stats_.messages == 0) m.message_start = m.message_end = log_time_ns;
  m.message_start = std::min(m.message_start, log_time_ns);
  m.message_end = std::max(m.message_end, log_time_ns);
  ++stats_.messages;
  ++m.channel_counts[channel_id];
  if (m.chunk.size() >= m.options.chunk_size_bytes) return flush_chunk();
  return {};
}

Status McapWriter::flush_chunk() {
  Impl& m = *impl_;
  if (m.chunk.empty()) return {};
  const std::size_t bound = ZSTD_compressBound(m.chunk.size());
  m.compressed.resize(bound);
  const std::size_t z = ZSTD_compress2(m.cctx, m.compressed.data(), bound, m.chunk.data(), m.chunk.size());
  if (ZSTD_isError(z)) return fail(std::string("zstd: ") + ZSTD_getErrorName(z));
  const std::uint64_t start = m.chunk_has_messages ? m.chunk_start : 0;
  const std::uint64_t end = m.chunk_has_messages ? m.chunk_end : 0;
  Bytes head;  // the chunk's fields before its records
  head.u64(start);
  head.u64(end);
  head.u64(m.chunk.size());
  head.u32(mcap_crc32(0, m.chunk.data(), m.chunk.size()));
  head.str("zstd");
  head.u64(z);
  const std::uint64_t content = head.b.size() + z;
  std::vector<std::uint8_t> rec;
  rec.push_back(static_cast<std::uint8_t>(McapOp::kChunk));
  for (int i = 0; i < 8; ++i) rec.push_back(static_cast<std::uint8_t>(content >> (8 * i)));
  rec.insert(rec.end(), head.b.begin(), head.b.end());
  const std::uint64_t chunk_offset = m.offset;
  const std::uint64_t chunk_length = rec.size() + z;
  m.data_crc = mcap_crc32(m.data_crc, rec.data(), rec.size());
  m.data_crc = mcap_crc32(m.data_crc, m.compressed.data(), z);
  if (Status s = write_raw(rec.data(), rec.size()); !s) return s;
  if (Status s = write_raw(m.compressed.data(), z); !s) return s;

  // One Message Index per channel in the chunk, right after it.
  std::map<std::uint16_t, std::uint64_t> index_offsets;
  const std::uint64_t indexes_start = m.offset;
  for (const auto& [channel, entries] : m.chunk_index) {
    Bytes idx;
    idx.u16(channel);
    idx.u32(static_cast<std::uint32_t>(entries.size() * 16));
    for (const auto& [t, off] : entries) {
      idx.u64(t);
      idx.u64(off);
    }
    std::vector<std::uint8_t> r;
    idx.record_into(McapOp::kMessageIndex, r);
    index_offsets[channel] = m.offset;
    m.data_crc = mcap_crc32(m.data_crc, r.data(), r.size());
    if (Status s = write_raw(r.data(), r.size()); !s) return s;
  }
  Bytes ci;
  ci.u64(start);
  ci.u64(end);
  ci.u64(chunk_offset);
  ci.u64(chunk_length);
  ci.u16_u64_map(index_offsets);
  ci.u64(m.offset - indexes_start);
  ci.str("zstd");
  ci.u64(z);
  ci.u64(m.chunk.size());
  m.chunk_indexes.push_back(std::move(ci));

  ++stats_.chunks;
  stats_.uncompressed_bytes += m.chunk.size();
  stats_.compressed_bytes += z;
  m.chunk.clear();
  m.chunk_index.clear();
  m.chunk_has_messages = false;
  return {};
}

Status McapWriter::write_metadata(const std::string& name, const std::map<std::string, std::string>& metadata) {
  Impl& m = *impl_;
  if (m.closed || m.failed) return fail("write_metadata() after close() or a failed write");
  // Outside chunks: close the open one first so the file stays in order.
  if (Status s = flush_chunk(); !s) return s;
  Bytes md;
  md.str(name);
  md.string_map(metadata);
  std::vector<std::uint8_t> r;
  md.record_into(McapOp::kMetadata, r);
  Bytes mi;
  mi.u64(m.offset);
  mi.u64(r.size());
  mi.str(name);
  m.metadata_indexes.push_back(std::move(mi));
  ++m.metadata_count;
  m.data_crc = mcap_crc32(m.data_crc, r.data(), r.size());
  return write_raw(r.data(), r.size());
}

Status McapWriter::close() {
  Impl& m = *impl_;
  if (m.closed) return {};
  if (m.failed) return fail("close() after a failed write: the file is incomplete");
  if (Status s = flush_chunk(); !s) return s;
  Bytes data_end;
  data_end.u32(m.data_crc);
  std::vector<std::uint8_t> rec;
  data_end.record_into(McapOp::kDataEnd, rec);
  if (Status s = write_raw(rec.data(), rec.size()); !s) return s;

  // The summary, grouped by opcode, and a Summary Offset per group.
  const std::uint64_t summary_start = m.offset;
  std::vector<std::uint8_t> summary;
  std::vector<Bytes> offsets;
  auto group = [&](McapOp op, const std::vector<Bytes>& records) {
    if (records.empty()) return;
    const std::uint64_t start = summary_start + summary.size();
    for (const Bytes& r : records) r.record_into(op, summary);
    Bytes so;
    so.u8(static_cast<std::uint8_t>(op));
    so.u64(start);
    so.u64(summary_start + summary.size() - start);
    offsets.push_back(std::move(so));
  };
  std::vector<Bytes> schemas, channels;
  for (const Schema& s : m.schemas)
    if (m.schemas_written.count(s.id)) schemas.push_back(schema_record(s));
  for (const Channel& c : m.channels)
    if (m.channels_written.count(c.id)) channels.push_back(channel_record(c));
  Bytes st;
  st.u64(stats_.messages);
  st.u16(static_cast<std::uint16_t>(schemas.size()));
  st.u32(static_cast<std::uint32_t>(channels.size()));
  st.u32(0);  // attachments
  st.u32(m.metadata_count);
  st.u32(static_cast<std::uint32_t>(stats_.chunks));
  st.u64(stats_.messages ? m.message_start : 0);
  st.u64(stats_.messages ? m.message_end : 0);
  st.u16_u64_map(m.channel_counts);
  group(McapOp::kSchema, schemas);
  group(McapOp::kChannel, channels);
  group(McapOp::kStatistics, {st});
  group(McapOp::kMetadataIndex, m.metadata_indexes);
  group(McapOp::kChunkIndex, m.chunk_indexes);
  const std::uint64_t summary_offset_start = summary_start + summary.size();
  for (const Bytes& so : offsets) so.record_into(McapOp::kSummaryOffset, summary);

  // Footer: the CRC covers the summary, the summary offsets and the footer up to its CRC field.
  std::vector<std::uint8_t> footer;
  footer.push_back(static_cast<std::uint8_t>(McapOp::kFooter));
  Bytes f;
  f.u64(20);
  f.u64(summary_start);
  f.u64(summary_offset_start);
  footer.insert(footer.end(), f.b.begin(), f.b.end());
  std::uint32_t crc = mcap_crc32(0, summary.data(), summary.size());
  crc = mcap_crc32(crc, footer.data(), footer.size());
  Bytes c;
  c.u32(crc);
  footer.insert(footer.end(), c.b.begin(), c.b.end());
  if (Status s = write_raw(summary.data(), summary.size()); !s) return s;
  if (Status s = write_raw(footer.data(), footer.size()); !s) return s;
  if (Status s = write_raw(kMcapMagic, sizeof kMcapMagic); !s) return s;
  m.closed = true;
  const int rc = std::fclose(m.file);
  m.file = nullptr;
  if (rc != 0) return fail(std::string("cannot close the file: ") + std::strerror(errno));
  return {};
}

}  // namespace augrig::recorder
