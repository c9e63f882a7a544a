// McapReader (mcap_reader.hpp): bounds-checked parsing of the MCAP records; a chunk is decompressed
// into a buffer of its declared size only after that size has been checked against a limit.
#include "recorder/mcap_reader.hpp"

#include <cstring>

#include <zstd.h>

#include "recorder/mcap_writer.hpp"

namespace augrig::recorder {
namespace {

// Largest uncompressed chunk accepted: far above what any writer makes (ours: about 4 MiB, or one
// image), low enough that a damaged size field cannot ask for all the memory there is.
constexpr std::uint64_t kMaxChunkBytes = 1ull << 32;
constexpr std::uint64_t kZstdBlockMaxBytes = 128 * 1024;  // ZSTD_BLOCKSIZE_MAX
constexpr std::uint64_t kFooterRecordBytes = 1 + 8 + 20;

// Reads fields off a byte range; any read past its end clears ok and returns zeros.
struct Cursor {
  const std::uint8_t* p;
  std::size_t n;
  std::size_t i = 0;
  bool ok = true;

  bool need(std::size_t k) {
    if (!ok || k > n - i) {
      ok = false;
      return false;
    }
    return true;
  }
  std::uint64_t le(int k) {
    if (!need(static_cast<std::size_t>(k))) return 0;
    std::uint64_t v = 0;
    for (int b = 0; b < k; ++b)
      v |= static_cast<std::uint64_t>(p[i + static_cast<std::size_t>(b)]) << (8 * b);
    i += static_cast<std::size_t>(k);
    return v;
  }
  std::uint8_t u8() { return static_cast<std::uint8_t>(le(1)); }
  std::uint16_t u16() { return static_cast<std::uint16_t>(le(2)); }
  std::uint32_t u32() { return static_cast<std::uint32_t>(le(4)); }
  std::uint64_t u64() { return le(8); }
  std::string str() {
    const std::uint32_t len = u32();
    if (!need(len)) return {};
    std::string s(reinterpret_cast<const char*>(p + i), len);
    i += len;
    return s;
  }
  std::map<std::string, std::string> string_map() {
    const std::uint32_t len = u32();
    std::map<std::string, std::string> m;
    if (!need(len)) return m;
    Cursor inner{p + i, len};
    while (inner.ok && inner.i < inner.n) {
      std::string k = inner.str();
      std::string v = inner.str();
      if (inner.ok) m.emplace(std::move(k), std::move(v));
    }
    ok = inner.ok;
    i += len;
    return m;
  }
  std::map<std::uint16_t, std::uint64_t> u16_u64_map() {
    const std::uint32_t len = u32();
    std::map<std::uint16_t, std::uint64_t> m;
    if (!need(len) || len % 10 != 0) {
      ok = false;
      return m;
    }
    for (std::uint32_t k = 0; k < len / 10; ++k) {
      const std::uint16_t key = u16();
      m[key] = u64();
    }
    return m;
  }
};

McapSchemaInfo parse_schema(Cursor& c) {
  McapSchemaInfo s;
  s.id = c.u16();
  s.name = c.str();
  s.encoding = c.str();
  s.data = c.str();
  return s;
}
McapChannelInfo parse_channel(Cursor& c) {
  McapChannelInfo ch;
  ch.id = c.u16();
  ch.schema_id = c.u16();
  ch.topic = c.str();
  ch.message_encoding = c.str();
  ch.metadata = c.string_map();
  return ch;
}

const char* op_name(std::uint8_t op) {
  switch (static_cast<McapOp>(op)) {
    case McapOp::kHeader:
      return "Header";
    case McapOp::kFooter:
      return "Footer";
    case McapOp::kSchema:
      return "Schema";
    case McapOp::kChannel:
      return "Channel";
    case McapOp::kMessage:
      return "Message";
    case McapOp::kChunk:
      return "Chunk";
    case McapOp::kMessageIndex:
      return "Message Index";
    case McapOp::kChunkIndex:
      return "Chunk Index";
    case McapOp::kAttachment:
      return "Attachment";
    case McapOp::kAttachmentIndex:
      return "Attachment Index";
    case McapOp::kStatistics:
      return "Statistics";
    case McapOp::kMetadata:
      return "Metadata";
    case McapOp::kMetadataIndex:
      return "Metadata Index";
    case McapOp::kSummaryOffset:
      return "Summary Offset";
    case McapOp::kDataEnd:
      return "Data End";
  }
  return "unknown";
}

std::string op_text(std::uint8_t op) {
  char hex[8];
  std::snprintf(hex, sizeof hex, "0x%02X", op);
  return std::string(op_name(op)) + " record (op " + hex + ")";
}

}  // namespace

McapReader::~McapReader() = default;

Error McapReader::error_at(std::uint64_t offset, const std::string& what) const {
  return Error{"recorder::McapReader: " + path_ + ": offset " + std::to_string(offset) + ": " + what};
}

Status McapReader::read_at(std::uint64_t offset, std::uint64_t n, std::vector<std::uint8_t>& out) {
  if (offset > size_ || n > size_ - offset)
    return error_at(offset, std::to_string(n) + " bytes wanted, the file ends at " + std::to_string(size_) +
                                " (truncated?)");
  out.resize(n);
  in_.clear();
  in_.seekg(static_cast<std::streamoff>(offset));
  if (n && !in_.read(reinterpret_cast<char*>(out.data()), static_cast<std::streamsize>(n)))
    return error_at(offset, "cannot read " + std::to_string(n) + " bytes");
  return {};
}

Expected<std::unique_ptr<McapReader>> McapReader::open(const std::string& path) {
  std::unique_ptr<McapReader> r(new McapReader());
  r->path_ = path;
  r->in_.open(path, std::ios::binary);
  if (!r->in_) return Error{"recorder::McapReader::open(): " + path + ": cannot open the file"};
  r->in_.seekg(0, std::ios::end);
  r->size_ = static_cast<std::uint64_t>(r->in_.tellg());
  std::vector<std::uint8_t> b;
  if (r->size_ < 8 || !r->read_at(0, 8, b) || std::memcmp(b.data(), kMcapMagic, 8) != 0)
    return r->error_at(0, "not an MCAP file: bad magic (expected 89 4D 43 41 50 30 0D 0A)");
  const std::uint64_t min_size = 8 + 9 + kFooterRecordBytes + 8;
  if (r->size_ < min_size || !r->read_at(r->size_ - 8, 8, b) || std::memcmp(b.data(), kMcapMagic, 8) != 0)
    return r->error_at(r->size_ >= 8 ? r->size_ - 8 : 0,
                       "no MCAP magic at the end of the file (" + std::to_string(r->size_) +
                           " bytes): the file is truncated or was not closed");
  // The Header.
  if (Status s = r->read_at(8, 9, b); !s) return s.error();
  Cursor hc{b.data(), b.size()};
  const std::uint8_t hop = hc.u8();
  const std::uint64_t hlen = hc.u64();
  if (hop != static_cast<std::uint8_t>(McapOp::kHeader) || hlen > r->size_ - 17)
    return r->error_at(
        8, "expected the Header record, found " + op_text(hop) + " of " + std::to_string(hlen) + " bytes");
  if (Status s = r->read_at(17, hlen, b); !s) return s.error();
  Cursor h{b.data(), b.size()};
  r->summary_.profile = h.str();
  r->summary_.library = h.str();
  if (!h.ok) return r->error_at(8, "Header record: fields run past its length");
  r->data_start_ = 17 + hlen;

  // The Footer.
  const std::uint64_t footer_at = r->size_ - 8 - kFooterRecordBytes;
  if (Status s = r->read_at(footer_at, kFooterRecordBytes, b); !s) return s.error();
  Cursor f{b.data(), b.size()};
  const std::uint8_t fop = f.u8();
  const std::uint64_t flen = f.u64();
  if (fop != static_cast<std::uint8_t>(McapOp::kFooter) || flen != 20)
    return r->error_at(footer_at, "expected the Footer record (op 0x02, 20 bytes), found " + op_text(fop) +
                                      " of " + std::to_string(flen) + " bytes");
  McapSummary& sum = r->summary_;
  sum.summary_start = f.u64();
  sum.summary_offset_start = f.u64();
  const std::uint32_t summary_crc = f.u32();
  if (sum.summary_start != 0 && (sum.summary_start < r->data_start_ || sum.summary_start > footer_at))
    return r->error_at(
        footer_at, "Footer: summary_start " + std::to_string(sum.summary_start) + " lies outside the file");
  if (sum.summary_offset_start != 0 &&
      (sum.summary_offset_start < sum.summary_start || sum.summary_offset_start > footer_at))
    return r->error_at(footer_at, "Footer: summary_offset_start " + std::to_string(sum.summary_offset_start) +
                                      " lies outside the summary");
  r->data_end_ = sum.summary_start ? sum.summary_start : footer_at;

  if (sum.summary_start) {
    std::vector<std::uint8_t> s;
    if (Status st = r->read_at(sum.summary_start, footer_at - sum.summary_start, s); !st) return st.error();
    if (summary_crc != 0) {
      std::uint32_t crc = mcap_crc32(0, s.data(), s.size());
      crc = mcap_crc32(crc, b.data(), 1 + 8 + 16);  // the footer up to its CRC field
      if (crc != summary_crc)
        return r->error_at(sum.summary_start, "summary CRC mismatch (footer says " +
                                                  std::to_string(summary_crc) + ", the bytes give " +
                                                  std::to_string(crc) + ")");
    }
    const std::size_t end = static_cast<std::size_t>(
        (sum.summary_offset_start ? sum.summary_offset_start : footer_at) - sum.summary_start);
    Cursor c{s.data(), end};
    while (c.i < c.n) {
      const std::uint64_t at = sum.summary_start + c.i;
      const std::uint8_t op = c.u8();
      const std::uint64_t len = c.u64();
      if (!c.ok || len > c.n - c.i)
        return r->error_at(at, op_text(op) + " in the summary runs past the summary");
      Cursor rc{s.data() + c.i, static_cast<std::size_t>(len)};
      switch (static_cast<McapOp>(op)) {
        case McapOp::kSchema: {
          McapSchemaInfo sc = parse_schema(rc);
          sum.schemas[sc.id] = sc;
          break;
        }
        case McapOp::kChannel: {
          McapChannelInfo ch = parse_channel(rc);
          sum.channels[ch.id] = ch;
          break;
        }
        case McapOp::kStatistics: {
          McapStatistics st;
          st.message_count = rc.u64();
          st.schema_count = rc.u16();
          st.channel_count = rc.u32();
          st.attachment_count = rc.u32();
          st.metadata_count = rc.u32();
          st.chunk_count = rc.u32();
          st.message_start_ns = rc.u64();
          st.message_end_ns = rc.u64();
          st.channel_message_counts = rc.u16_u64_map();
          sum.statistics = st;
          break;
        }
        case McapOp::kChunkIndex: {
          McapChunkIndex ci;
          ci.message_start_ns = rc.u64();
          ci.message_end_ns = rc.u64();
          ci.chunk_offset = rc.u64();
          ci.chunk_length = rc.u64();
          ci.message_index_offsets = rc.u16_u64_map();
          ci.message_index_length = rc.u64();
          ci.compression = rc.str();
          ci.compressed_size = rc.u64();
          ci.uncompressed_size = rc.u64();
          sum.chunk_indexes.push_back(ci);
          break;
        }
        case McapOp::kMetadataIndex: {
          const std::uint64_t off = rc.u64();
          rc.u64();  // length
          sum.metadata_offsets[rc.str()] = off;
          break;
        }
        default:
          break;  // attachment indexes and records unknown to this reader
      }
      if (!rc.ok) return r->error_at(at, op_text(op) + " in the summary: fields run past its length");
      c.i += static_cast<std::size_t>(len);
    }
  }
  r->channels_ = sum.channels;
  r->schemas_ = sum.schemas;
  r->rewind();
  return r;
}

std::uint16_t McapReader::channel_id(const std::string& topic) const {
  for (const auto& [id, c] : channels_)
    if (c.topic == topic) return id;
  return 0;
}

void McapReader::rewind() {
  pos_ = data_start_;
  done_ = false;
  chunk_.clear();
  chunk_pos_ = 0;
}

Expected<std::optional<std::map<std::string, std::string>>> McapReader::metadata(const std::string& name) {
  const auto it = summary_.metadata_offsets.find(name);
  if (it == summary_.metadata_offsets.end()) return std::optional<std::map<std::string, std::string>>{};
  std::vector<std::uint8_t> b;
  if (Status s = read_at(it->second, 9, b); !s) return s.error();
  Cursor h{b.data(), b.size()};
  const std::uint8_t op = h.u8();
  const std::uint64_t len = h.u64();
  if (op != static_cast<std::uint8_t>(McapOp::kMetadata))
    return error_at(it->second, "the Metadata Index of '" + name + "' points at a " + op_text(op));
  if (Status s = read_at(it->second + 9, len, b); !s) return s.error();
  Cursor c{b.data(), b.size()};
  if (c.str() != name || !c.ok)
    return error_at(it->second, "Metadata record: not the one named '" + name + "'");
  auto m = c.string_map();
  if (!c.ok) return error_at(it->second, "Metadata record '" + name + "': fields run past its length");
  return std::optional<std::map<std::string, std::string>>(std::move(m));
}

Expected<bool> McapReader::next(McapMessage& out) {
  while (!done_) {
    // Inside a chunk: its records one by one.
    if (chunk_pos_ < chunk_.size()) {
      Cursor c{chunk_.data() + chunk_pos_, chunk_.size() - chunk_pos_};
      const std::size_t at = chunk_pos_;
      const std::uint8_t op = c.u8();
      const std::uint64_t len = c.u64();
      if (!c.ok || len > c.n - c.i)
        return error_at(chunk_offset_, "Chunk: " + op_text(op) + " at offset " + std::to_string(at) +
                                           " of the uncompressed chunk runs past the chunk's end");
      Cursor rc{c.p + c.i, static_cast<std::size_t>(len)};
      chunk_pos_ += c.i + static_cast<std::size_t>(len);
      if (op == static_cast<std::uint8_t>(McapOp::kMessage)) {
        out.channel_id = rc.u16();
        out.sequence = rc.u32();
        out.log_time_ns = rc.u64();
        out.publish_time_ns = rc.u64();
        if (!rc.ok)
          return error_at(chunk_offset_,
                          "Chunk: Message record at offset " + std::to_string(at) + " is too short");
        if (!channels_.count(out.channel_id))
          return error_at(chunk_offset_, "Chunk: Message at offset " + std::to_string(at) + " on channel " +
                                             std::to_string(out.channel_id) +
                                             ", which no Channel record defines");
        out.data.assign(rc.p + rc.i, rc.p + rc.n);
        return true;
      }
      if (op == static_cast<std::uint8_t>(McapOp::kSchema)) {
        McapSchemaInfo s = parse_schema(rc);
        if (!rc.ok)
          return error_at(chunk_offset_,
                          "Chunk: Schema record at offset " + std::to_string(at) + " is damaged");
        schemas_[s.id] = s;
      } else if (op == static_cast<std::uint8_t>(McapOp::kChannel)) {
        McapChannelInfo ch = parse_channel(rc);
        if (!rc.ok)
          return error_at(chunk_offset_,
                          "Chunk: Channel record at offset " + std::to_string(at) + " is damaged");
        channels_[ch.id] = ch;
      }
      continue;
    }
    // The data section's next record.
    if (pos_ >= data_end_) return error_at(pos_, "the data section ends without a Data End record");
    const std::uint64_t at = pos_;
    if (Status s = read_at(at, 9, record_); !s) return s.error();
    Cursor h{record_.data(), record_.size()};
    const std::uint8_t op = h.u8();
    const std::uint64_t len = h.u64();
    if (op == 0) return error_at(at, "opcode 0 is not a record: the data section is damaged");
    if (len > data_end_ - at - 9)
      return error_at(at, op_text(op) + " of " + std::to_string(len) +
                              " bytes runs past the data section (ends at " + std::to_string(data_end_) +
                              ")");
    pos_ = at + 9 + len;
    switch (static_cast<McapOp>(op)) {
      case McapOp::kDataEnd:
        done_ = true;
        return false;
      case McapOp::kChunk: {
        if (Status s = read_at(at + 9, len, record_); !s) return s.error();
        Cursor c{record_.data(), record_.size()};
        c.u64();
        c.u64();  // message start and end times
        const std::uint64_t usize = c.u64();
        const std::uint32_t crc = c.u32();
        const std::string compression = c.str();
        const std::uint64_t csize = c.u64();
        if (!c.ok || csize > c.n - c.i)
          return error_at(at, "Chunk: its records (" + std::to_string(csize) + " bytes) run past the record");
        if (usize > kMaxChunkBytes)
          return error_at(at, "Chunk: uncompressed size " + std::to_string(usize) + " bytes is implausible");
        // Said before anything is allocated: stored records are as long as the uncompressed ones, and
        // no zstd data gives more than one block (128 KiB) per 4 bytes (a block's header and a byte).
        if (compression.empty() && csize != usize)
          return error_at(at, "Chunk: uncompressed, but its sizes differ");
        if (compression == "zstd" && usize > (csize / 4 + 1) * kZstdBlockMaxBytes)
          return error_at(at, "Chunk: uncompressed size " + std::to_string(usize) +
                                  " bytes is more than its " + std::to_string(csize) +
                                  " bytes of zstd data can give");
        chunk_.resize(static_cast<std::size_t>(usize));
        if (compression == "zstd") {
          const std::size_t got =
              ZSTD_decompress(chunk_.data(), chunk_.size(), c.p + c.i, static_cast<std::size_t>(csize));
          if (ZSTD_isError(got)) {
            chunk_.clear();
            return error_at(at, std::string("Chunk: zstd: ") + ZSTD_getErrorName(got));
          }
          if (got != usize) {
            chunk_.clear();
            return error_at(at, "Chunk: decompressed to " + std::to_string(got) + " bytes, the chunk says " +
                                    std::to_string(usize));
          }
        } else if (compression.empty()) {
          if (usize)
            std::memcpy(chunk_.data(), c.p + c.i, static_cast<std::size_t>(usize));  // none: no buffer
        } else {
          chunk_.clear();
          return error_at(at, "Chunk: compression '" + compression + "' is not supported (zstd or none)");
        }
        if (crc != 0 && mcap_crc32(0, chunk_.data(), chunk_.size()) != crc) {
          chunk_.clear();
          return error_at(at, "Chunk: CRC mismatch of the uncompressed records (the chunk is damaged)");
        }
        chunk_pos_ = 0;
        chunk_offset_ = at;
        break;
      }
      case McapOp::kSchema:
      case McapOp::kChannel:
      case McapOp::kMessage: {
        // Outside chunks (other writers): parse from the file.
        if (Status s = read_at(at + 9, len, record_); !s) return s.error();
        Cursor rc{record_.data(), record_.size()};
        if (op == static_cast<std::uint8_t>(McapOp::kSchema)) {
          McapSchemaInfo s = parse_schema(rc);
          if (rc.ok) schemas_[s.id] = s;
        } else if (op == static_cast<std::uint8_t>(McapOp::kChannel)) {
          McapChannelInfo ch = parse_channel(rc);
          if (rc.ok) channels_[ch.id] = ch;
        } else {
          out.channel_id = rc.u16();
          out.sequence = rc.u32();
          out.log_time_ns = rc.u64();
          out.publish_time_ns = rc.u64();
          if (rc.ok && !channels_.count(out.channel_id))
            return error_at(at, "Message on channel " + std::to_string(out.channel_id) +
                                    ", which no Channel record defines");
          if (rc.ok) {
            out.data.assign(rc.p + rc.i, rc.p + rc.n);
            return true;
          }
        }
        if (!rc.ok) return error_at(at, op_text(op) + ": fields run past its length");
        break;
      }
      default:
        break;  // message indexes, metadata, attachments, records unknown to this reader
    }
  }
  return false;
}

}  // namespace augrig::recorder
