// ImageFolderSource (files://): frames and timestamps from a frame index, pairing by timestamp through
// the StereoSource, the errors that name the index's file and line, and left/right folders paired by
// sorted name.
#include "pipeline/image_folder_source.hpp"

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "pipeline/sources.hpp"
#include "render/image_file.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::pipeline {
namespace {

namespace fs = std::filesystem;

// A small gray image whose first pixel says which one it is.
void write_image(const fs::path& path, int w, int h, std::uint8_t mark) {
  fs::create_directories(path.parent_path());
  Image im(w, h, PixelFormat::kMono8);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) im.row(y)[x] = static_cast<std::uint8_t>(x + y);
  im.row(0)[0] = mark;
  ASSERT_TRUE(write_png_file(path.string(), im));
}

// A dataset as `augrig sim` writes it: frames/index.csv with left/NNNNNN.png and right/NNNNNN.png at
// 10 Hz (t0 + 100 ms per sequence), the right camera's clock `skew_ns` ahead.
std::string make_index(const std::string& name, const std::vector<std::string>& rows) {
  const fs::path dir = fs::path(test::output_dir(name)) / "frames";
  fs::create_directories(dir);
  std::ofstream f(dir / "index.csv");
  f << "# augrig frame index (docs/NAV_FORMATS.md)\n# clock: device\nsequence,camera,t_ns,file\n";
  for (const std::string& r : rows) f << r << "\n";
  return (dir / "index.csv").string();
}

std::string row(std::uint64_t seq, int cam, std::int64_t t_ns) {
  char name[32];
  std::snprintf(name, sizeof name, "%06llu.png", static_cast<unsigned long long>(seq));
  return std::to_string(seq) + "," + std::to_string(cam) + "," + std::to_string(t_ns) + "," +
         (cam == 0 ? "left/" : "right/") + name;
}

constexpr std::int64_t kT0 = 1'000'000'000'000;

// Writes each row's image (8x6, marked with sequence * 2 + camera).
void write_images(const std::string& index, const std::vector<std::pair<std::uint64_t, int>>& frames) {
  const fs::path dir = fs::path(index).parent_path();
  for (auto [seq, cam] : frames) {
    char name[32];
    std::snprintf(name, sizeof name, "%06llu.png", static_cast<unsigned long long>(seq));
    write_image(dir / (cam == 0 ? "left" : "right") / name, 8, 6, static_cast<std::uint8_t>(seq * 2 + cam));
  }
}

TEST(ImageFolderSource, IndexFramesCarryTheirTimestampsCameraAndSequence) {
  const std::int64_t skew = 40'000;  // the right clock 40 us ahead
  const std::string index =
      make_index("ifs_index", {row(0, 0, kT0), row(0, 1, kT0 + skew), row(1, 0, kT0 + 100'000'000),
                               row(1, 1, kT0 + 100'000'000 + skew), row(2, 1, kT0 + 200'000'000 + skew),
                               row(2, 0, kT0 + 200'000'000)});
  write_images(index, {{0, 0}, {0, 1}, {1, 0}, {1, 1}, {2, 0}, {2, 1}});
  auto src = ImageFolderSource::open_index(index);
  ASSERT_TRUE(src) << src.error().message;
  EXPECT_TRUE((*src)->from_index());
  EXPECT_EQ((*src)->clock(), ClockDomain::kDevice);
  EXPECT_EQ((*src)->half_median_interval_ns(), 50'000'000);
  EXPECT_EQ((*src)->expected_pairs(50'000'000), 3u);
  EXPECT_EQ((*src)->expected_pairs(10'000), 0u) << "40 us apart: no pair within 10 us";
  // Delivered in time order (the last two rows swapped back), each with its row's facts.
  const std::pair<std::uint64_t, int> order[] = {{0, 0}, {0, 1}, {1, 0}, {1, 1}, {2, 0}, {2, 1}};
  for (auto [seq, cam] : order) {
    Frame f;
    auto r = (*src)->read(f, {});
    ASSERT_TRUE(r) << r.error().message;
    ASSERT_EQ(*r, ReadStatus::kFrame);
    EXPECT_EQ(f.sequence, seq);
    EXPECT_EQ(index_of(f.camera), cam);
    EXPECT_EQ(f.t_ns, kT0 + static_cast<std::int64_t>(seq) * 100'000'000 + (cam ? skew : 0));
    EXPECT_EQ(f.clock, ClockDomain::kDevice);
    EXPECT_EQ(f.image.width(), 8);
    EXPECT_EQ(f.image.row(0)[0], seq * 2 + static_cast<std::uint64_t>(cam));
    const auto* a = dynamic_cast<const ImageFileAttachment*>(f.attachment.get());
    ASSERT_NE(a, nullptr);
    EXPECT_NE(a->path.find(cam ? "right/" : "left/"), std::string::npos) << a->path;
  }
  Frame f;
  EXPECT_EQ(*(*src)->read(f, {}), ReadStatus::kEndOfStream);
}

TEST(ImageFolderSource, UriPairsByTimestampWithinHalfTheMedianIntervalAndCountsTheUnpaired) {
  // Sequence 1 has no right frame: its left frame is counted unpaired, never paired with a neighbour.
  const std::string index = make_index(
      "ifs_pairing", {row(0, 0, kT0), row(0, 1, kT0 + 30'000), row(1, 0, kT0 + 100'000'000),
                      row(2, 0, kT0 + 200'000'000), row(2, 1, kT0 + 200'030'000), row(3, 0, kT0 + 300'000'000),
                      row(3, 1, kT0 + 300'030'000)});
  write_images(index, {{0, 0}, {0, 1}, {1, 0}, {2, 0}, {2, 1}, {3, 0}, {3, 1}});
  auto opened = open_sources("files://" + index);
  ASSERT_TRUE(opened) << opened.error().message;
  EXPECT_TRUE(opened->options.lossless);
  EXPECT_FALSE(opened->live);
  EXPECT_EQ(opened->options.pairing.mode, PairingMode::kTimestamp);
  // Left intervals 100, 100, 100 ms and right 200, 100 ms: median 100 ms, tolerance 50 ms.
  EXPECT_EQ(opened->options.pairing.tolerance_ns, 50'000'000);
  // Its counts as capabilities: the pairs that tolerance forms, every image; the typed handle.
  EXPECT_TRUE(opened->sources.front()->capabilities().finite);
  EXPECT_FALSE(opened->sources.front()->capabilities().seekable);
  EXPECT_EQ(opened->sources.front()->pair_count(), 3u);
  EXPECT_EQ(opened->sources.front()->image_count(), 7u);
  EXPECT_EQ(opened->image_files, opened->sources.front().get());
  auto stereo = start_stereo(std::move(*opened));
  ASSERT_TRUE(stereo) << stereo.error().message;
  std::vector<std::uint64_t> sequences;
  for (;;) {
    StereoFrame sf;
    auto r = (*stereo)->read(sf, std::chrono::seconds(5));
    ASSERT_TRUE(r) << r.error().message;
    if (*r == ReadStatus::kEndOfStream) break;
    if (*r != ReadStatus::kFrame) continue;
    EXPECT_EQ(sf.left.sequence, sf.right.sequence);
    EXPECT_EQ(sf.skew_ns, 30'000);
    ASSERT_TRUE(sf.left.attachment);
    EXPECT_EQ(fs::path(sf.left.attachment->file_path()).extension(), ".png");
    EXPECT_FALSE(sf.left.attachment->position()) << "an image file has no recorded position";
    sequences.push_back(sf.left.sequence);
  }
  EXPECT_EQ(sequences, (std::vector<std::uint64_t>{0, 2, 3}));
  const StereoSourceStats st = (*stereo)->stats();
  EXPECT_EQ(st.pairing.unpaired_left, 1u);
  EXPECT_EQ(st.pairing.unpaired_right, 0u);
  EXPECT_EQ(st.frames[0] + st.frames[1], 2 * 3 + 1u) << "read = 2 x pairs + unpaired";

  // An explicit tolerance below the skew pairs nothing; a bad one is an error naming it.
  auto tight = open_sources("files://" + index + "?tolerance_us=10");
  ASSERT_TRUE(tight) << tight.error().message;
  EXPECT_EQ(tight->options.pairing.tolerance_ns, 10'000);
  auto bad = open_sources("files://" + index + "?tolerance_us=-1");
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("tolerance_us"), std::string::npos) << bad.error().message;
  auto unknown = open_sources("files://" + index + "?every=2");
  ASSERT_FALSE(unknown);
  EXPECT_NE(unknown.error().message.find("unknown parameter every"), std::string::npos) << unknown.error().message;
}

TEST(ImageFolderSource, MissingFileIsNamedWithItsIndexRow) {
  const std::string index = make_index("ifs_missing", {row(0, 0, kT0), row(0, 1, kT0), row(1, 0, kT0 + 100'000'000),
                                                       row(1, 1, kT0 + 100'000'000)});
  write_images(index, {{0, 0}, {0, 1}, {1, 1}});  // left/000001.png is missing
  auto src = open_sources("files://" + index);
  ASSERT_FALSE(src);
  const std::string& m = src.error().message;
  // Line 6: two comment lines, the header, then the third row.
  EXPECT_NE(m.find(index + ":6: file 'left/000001.png' (camera 0, sequence 1): no such file"), std::string::npos)
      << m;
}

TEST(ImageFolderSource, BadIndexRowNamesFileAndLine) {
  const std::string index = make_index("ifs_bad_row", {row(0, 0, kT0), "1,0,soon,left/000001.png"});
  auto src = ImageFolderSource::open_index(index);
  ASSERT_FALSE(src);
  EXPECT_NE(src.error().message.find(index + ":5"), std::string::npos) << src.error().message;
  EXPECT_NE(src.error().message.find("t_ns"), std::string::npos) << src.error().message;

  // A third camera is not a stereo rig's.
  const std::string three = make_index("ifs_camera_2", {row(0, 0, kT0), row(0, 1, kT0), "0,2,1000,left/000000.png"});
  write_images(three, {{0, 0}, {0, 1}});
  src = ImageFolderSource::open_index(three);
  ASSERT_FALSE(src);
  EXPECT_NE(src.error().message.find(three + ":6: column 'camera': expected 0 (left) or 1 (right)"), std::string::npos)
      << src.error().message;

  // One camera only: nothing could pair.
  const std::string left_only = make_index("ifs_left_only", {row(0, 0, kT0)});
  write_images(left_only, {{0, 0}});
  src = ImageFolderSource::open_index(left_only);
  ASSERT_FALSE(src);
  EXPECT_NE(src.error().message.find("no frame of camera 1 (right)"), std::string::npos) << src.error().message;
}

TEST(ImageFolderSource, FoldersPairBySortedName) {
  const fs::path dir = test::output_dir("ifs_folders");
  fs::remove_all(dir / "L");
  fs::remove_all(dir / "R");
  // Names differ between the folders; the order of the sorted names pairs them.
  write_image(dir / "L" / "b.png", 8, 6, 11);
  write_image(dir / "L" / "a.png", 8, 6, 10);
  write_image(dir / "R" / "y.png", 8, 6, 21);
  write_image(dir / "R" / "x.png", 8, 6, 20);
  std::ofstream(dir / "L" / "notes.txt") << "not an image\n";
  auto opened = open_sources("files://folders?left=" + (dir / "L").string() + "&right=" + (dir / "R").string());
  ASSERT_TRUE(opened) << opened.error().message;
  EXPECT_EQ(opened->options.pairing.mode, PairingMode::kAdjacent);
  auto stereo = start_stereo(std::move(*opened));
  ASSERT_TRUE(stereo) << stereo.error().message;
  std::vector<std::pair<int, int>> marks;
  std::vector<TimestampNs> keys;
  for (;;) {
    StereoFrame sf;
    auto r = (*stereo)->read(sf, std::chrono::seconds(5));
    ASSERT_TRUE(r) << r.error().message;
    if (*r == ReadStatus::kEndOfStream) break;
    if (*r != ReadStatus::kFrame) continue;
    marks.emplace_back(sf.left.image.row(0)[0], sf.right.image.row(0)[0]);
    keys.push_back(sf.t_key_ns);
  }
  EXPECT_EQ(marks, (std::vector<std::pair<int, int>>{{10, 20}, {11, 21}}));
  EXPECT_EQ(keys, (std::vector<TimestampNs>{0, 1})) << "a pair's t_ns is its index";

  // Counts that differ are an error naming both folders; so is a folder with a file.
  write_image(dir / "L" / "c.png", 8, 6, 12);
  auto uneven = ImageFolderSource::open_folders((dir / "L").string(), (dir / "R").string());
  ASSERT_FALSE(uneven);
  EXPECT_NE(uneven.error().message.find((dir / "L").string() + " has 3"), std::string::npos) << uneven.error().message;
  EXPECT_NE(uneven.error().message.find((dir / "R").string() + " has 2"), std::string::npos) << uneven.error().message;
  auto mixed = ImageFolderSource::open_folders((dir / "L").string(), (dir / "R" / "x.png").string());
  ASSERT_FALSE(mixed);
  EXPECT_NE(mixed.error().message.find("must both be image files or both folders"), std::string::npos);
  // Two files are one pair.
  auto one = ImageFolderSource::open_folders((dir / "L" / "a.png").string(), (dir / "R" / "x.png").string());
  ASSERT_TRUE(one) << one.error().message;
  EXPECT_EQ((*one)->expected_pairs(0), 1u);
}

}  // namespace
}  // namespace augrig::pipeline
