// McapWriter and McapReader (recorder/mcap_writer.hpp, mcap_reader.hpp) and the CDR of
// ros2/messages.hpp: messages across many chunks come back in order with their indexes and
// statistics; any truncation or flipped byte of a file is an Error (or, for bytes no check covers,
// a file that still reads), never a crash; images, poses and statistics through CDR bit for bit.
// The independent readers from npm check the same files in tests/app/cmd_export_mcap_test.cpp.
#include "recorder/mcap_writer.hpp"

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "recorder/mcap_reader.hpp"
#include "ros2/messages.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::recorder {
namespace {

std::vector<std::uint8_t> payload(int i) {
  std::vector<std::uint8_t> p(static_cast<std::size_t>(50 + (i * 37) % 300));
  for (std::size_t k = 0; k < p.size(); ++k) p[k] = static_cast<std::uint8_t>(i * 7 + static_cast<int>(k));
  return p;
}

// 300 messages on two channels in chunks of about 2 KiB, and a metadata record.
std::string write_sample(const std::string& path) {
  McapWriterOptions o;
  o.chunk_size_bytes = 2048;
  auto w = McapWriter::create(path, o);
  EXPECT_TRUE(w) << w.error().message;
  const auto s = (*w)->add_schema("test/msg/A", "ros2msg", "uint8[] data\n");
  const auto a = (*w)->add_channel(s, "/a", "cdr", {{"k", "v"}});
  const auto b = (*w)->add_channel(s, "/b", "cdr", {});
  EXPECT_TRUE((*w)->write_metadata("meta", {{"rig_yaml", "cameras: []"}}));
  for (int i = 0; i < 300; ++i) EXPECT_TRUE((*w)->write_message(i % 3 ? a : b, 1000 + 10 * i, payload(i)));
  EXPECT_TRUE((*w)->close());
  EXPECT_GT((*w)->stats().chunks, 10u);
  return path;
}

std::vector<std::uint8_t> bytes_of(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
void write_bytes(const std::string& path, const std::vector<std::uint8_t>& b) {
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
}

// Opens and reads every message; the first Error, or "" when the file read to its Data End.
std::string read_all(const std::string& path, std::size_t* messages = nullptr) {
  auto r = McapReader::open(path);
  if (!r) return r.error().message;
  McapMessage m;
  std::size_t n = 0;
  while (true) {
    auto more = (*r)->next(m);
    if (!more) return more.error().message;
    if (!*more) break;
    ++n;
  }
  if (messages) *messages = n;
  return "";
}

TEST(McapWriter, MessagesComeBackInOrderWithTheirIndexesAndStatistics) {
  const std::string path = write_sample(test::output_dir("mcap_writer_order") + "/a.mcap");
  auto r = McapReader::open(path);
  ASSERT_TRUE(r) << r.error().message;
  const McapSummary& s = (*r)->summary();
  EXPECT_EQ(s.profile, "ros2");
  ASSERT_TRUE(s.statistics);
  EXPECT_EQ(s.statistics->message_count, 300u);
  EXPECT_EQ(s.statistics->channel_count, 2u);
  EXPECT_EQ(s.statistics->schema_count, 1u);
  EXPECT_EQ(s.statistics->metadata_count, 1u);
  EXPECT_EQ(s.statistics->message_start_ns, 1000u);
  EXPECT_EQ(s.statistics->message_end_ns, 1000u + 10 * 299);
  EXPECT_EQ(s.statistics->channel_message_counts.at((*r)->channel_id("/a")), 200u);
  EXPECT_EQ(s.statistics->channel_message_counts.at((*r)->channel_id("/b")), 100u);
  EXPECT_EQ(s.chunk_indexes.size(), s.statistics->chunk_count);
  EXPECT_EQ(s.channels.at((*r)->channel_id("/a")).metadata.at("k"), "v");
  for (const McapChunkIndex& c : s.chunk_indexes) {
    EXPECT_EQ(c.compression, "zstd");
    EXPECT_FALSE(c.message_index_offsets.empty());
    EXPECT_LE(c.message_start_ns, c.message_end_ns);
  }
  auto meta = (*r)->metadata("meta");
  ASSERT_TRUE(meta && *meta);
  EXPECT_EQ((*meta)->at("rig_yaml"), "cameras: []");
  McapMessage m;
  for (int i = 0; i < 300; ++i) {
    auto more = (*r)->next(m);
    ASSERT_TRUE(more && *more) << i;
    EXPECT_EQ(m.log_time_ns, 1000u + 10u * static_cast<unsigned>(i));
    EXPECT_EQ((*r)->channels().at(m.channel_id).topic, i % 3 ? "/a" : "/b");
    EXPECT_EQ(m.data, payload(i)) << i;
  }
  auto end = (*r)->next(m);
  ASSERT_TRUE(end);
  EXPECT_FALSE(*end);
}

TEST(McapReader, TruncatedOrFlippedBytesAreErrorsNeverCrashes) {
  const std::string dir = test::output_dir("mcap_reader_damage");
  const std::vector<std::uint8_t> good = bytes_of(write_sample(dir + "/good.mcap"));
  std::size_t n = 0;
  ASSERT_EQ(read_all(dir + "/good.mcap", &n), "");
  EXPECT_EQ(n, 300u);
  const std::string bad = dir + "/bad.mcap";
  // Every truncation is refused when the file is opened (no magic at the end).
  // About 300 cuts and 300 flips spread over the file (each one a file written and read).
  const std::size_t step = good.size() / 300 + 1;
  for (std::size_t len = 0; len < good.size(); len += step) {
    write_bytes(bad,
                std::vector<std::uint8_t>(good.begin(), good.begin() + static_cast<std::ptrdiff_t>(len)));
    const std::string e = read_all(bad);
    EXPECT_NE(e.find(bad), std::string::npos) << len << ": " << e;
  }
  write_bytes(bad, std::vector<std::uint8_t>(good.begin(), good.end() - 1));
  EXPECT_NE(read_all(bad).find("the file is truncated or was not closed"), std::string::npos);
  // Flipped bytes anywhere: an Error or a file that still reads (bytes no check covers, such as
  // the sequence numbers); whatever comes, no crash and no hang.
  std::size_t errors = 0;
  std::size_t tries = 0;
  for (std::size_t at = 0; at < good.size(); at += step) {
    ++tries;
    std::vector<std::uint8_t> b = good;
    b[at] ^= 0x5A;
    write_bytes(bad, b);
    errors += !read_all(bad).empty();
  }
  EXPECT_GT(errors, tries / 2);  // chunks are CRC-checked and compressed: most flips are caught
  std::vector<std::uint8_t> b = good;
  b[0] = 'X';
  write_bytes(bad, b);
  EXPECT_NE(read_all(bad).find(bad + ": offset 0: not an MCAP file: bad magic"), std::string::npos);
}

// A chunk that says it holds 1 GiB of records in a few hundred bytes of zstd data (found by
// fuzz_mcap: the reader allocated the gigabyte, then zstd failed) is refused before anything is
// allocated: no zstd data gives more than 128 KiB per 4 bytes.
TEST(McapReader, AChunkClaimingMoreThanItsBytesCanGiveIsRefused) {
  const std::string dir = test::output_dir("mcap_reader_chunk_size");
  std::vector<std::uint8_t> b = bytes_of(write_sample(dir + "/good.mcap"));
  std::size_t at = 8;  // the records after the magic: the first Chunk (opcode 0x06)
  auto u64 = [&](std::size_t p) {
    std::uint64_t v = 0;
    for (int k = 7; k >= 0; --k) v = (v << 8) | b[p + static_cast<std::size_t>(k)];
    return v;
  };
  while (at + 9 < b.size() && b[at] != 0x06) at += 9 + static_cast<std::size_t>(u64(at + 1));
  ASSERT_LT(at + 9 + 24, b.size());
  const std::size_t usize_at = at + 9 + 16;  // after the message start and end times
  EXPECT_LT(u64(usize_at), 4096u);
  const std::uint64_t gib = 1ull << 30;
  for (int k = 0; k < 8; ++k)
    b[usize_at + static_cast<std::size_t>(k)] = static_cast<std::uint8_t>(gib >> (8 * k));
  write_bytes(dir + "/claims.mcap", b);
  const std::string e = read_all(dir + "/claims.mcap");
  EXPECT_NE(e.find(dir + "/claims.mcap: offset " + std::to_string(at) +
                   ": Chunk: uncompressed size 1073741824 bytes is more than its "),
            std::string::npos)
      << e;
  EXPECT_NE(e.find(" bytes of zstd data can give"), std::string::npos) << e;
  // An empty chunk stored without compression (also found by fuzz_mcap: the reader copied 0 bytes
  // from a buffer that was never allocated, which UBSan stops) reads as no records.
  std::size_t p = usize_at;
  auto put64 = [&](std::uint64_t v) {
    for (int k = 0; k < 8; ++k) b[p++] = static_cast<std::uint8_t>(v >> (8 * k));
  };
  put64(0);                                // uncompressed size
  for (int k = 0; k < 8; ++k) b[p++] = 0;  // CRC 0 (none), compression "" (length 0)
  put64(0);                                // the records: none (the rest of the record is left over)
  write_bytes(dir + "/empty.mcap", b);
  const std::string empty = read_all(dir + "/empty.mcap");
  EXPECT_EQ(empty.find("Chunk: uncompressed"), std::string::npos) << empty;
}

TEST(Ros2Cdr, ImagesPosesAndStatisticsRoundTripBitForBit) {
  Image im(6, 4, PixelFormat::kBayerGR8);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 6; ++x) im.row(y)[x] = static_cast<std::uint8_t>(17 * y + x);
  const std::vector<std::uint8_t> msg = ros2::image(1'500'000'007, "left_camera", im.cview());
  // Encapsulation header (CDR little endian), then sec = 1, nanosec = 500000007.
  ASSERT_GE(msg.size(), 12u);
  EXPECT_EQ(std::vector<std::uint8_t>(msg.begin(), msg.begin() + 4), (std::vector<std::uint8_t>{0, 1, 0, 0}));
  EXPECT_EQ(msg[4], 1);
  std::int64_t stamp = 0;
  auto back = ros2::decode_image(msg, &stamp);
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_EQ(stamp, 1'500'000'007);
  EXPECT_EQ(back->format(), PixelFormat::kBayerGR8);
  EXPECT_TRUE(pixels_equal(*back, im));
  EXPECT_EQ(ros2::image_encoding(PixelFormat::kBayerRG8), "bayer_rggb8");
  EXPECT_EQ(ros2::image_encoding(PixelFormat::kBayerBG8), "bayer_bggr8");
  // Truncated messages are errors.
  for (std::size_t len = 0; len < msg.size(); ++len)
    EXPECT_FALSE(ros2::decode_image(
        std::vector<std::uint8_t>(msg.begin(), msg.begin() + static_cast<std::ptrdiff_t>(len))));

  const Pose p = pose_from_ypr(Eigen::Vector3d(0.1, -2.3, 45.6), 0.3, -0.2, 0.1);
  auto pose = ros2::decode_pose_with_covariance(ros2::pose_with_covariance(5, "left_camera", p, {}));
  ASSERT_TRUE(pose);
  EXPECT_EQ(pose->translation_m, p.translation_m);
  EXPECT_EQ(pose->rotation.coeffs(), p.rotation.coeffs());
  auto tf = ros2::decode_tf_message(ros2::tf_message({{7, "tanker_body", "receiver_body", p}}));
  ASSERT_TRUE(tf);
  ASSERT_EQ(tf->size(), 1u);
  EXPECT_EQ((*tf)[0].child, "receiver_body");
  EXPECT_EQ((*tf)[0].T_parent_child.rotation.coeffs(), p.rotation.coeffs());

  OcclusionStats s;
  s.t_ns = 99;
  s.receiver_px_left = 12345;
  s.boom_pct_right = 1.0 / 3.0;
  auto st = ros2::decode_occlusion_stats(ros2::occlusion_stats(99, s));
  ASSERT_TRUE(st);
  EXPECT_EQ(st->receiver_px_left, 12345);
  EXPECT_EQ(st->boom_pct_right, 1.0 / 3.0);
  EXPECT_FALSE(ros2::check_stamp(-1));
  // Every schema names its dependencies after a line of 80 '=' (rosbag2's concatenation).
  for (const std::string& type : ros2::known_types()) {
    const std::string text = ros2::schema_text(type);
    ASSERT_FALSE(text.empty()) << type;
    if (text.find("std_msgs/Header header") != std::string::npos) {
      EXPECT_NE(text.find(std::string(80, '=') + "\nMSG: std_msgs/Header\n"), std::string::npos) << type;
    }
  }
}

}  // namespace
}  // namespace augrig::recorder
