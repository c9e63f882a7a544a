// .npy files: the bytes the NumPy format specification prescribes (magic, version, a header
// padded to 64 bytes, little-endian float32), a round trip, and clear errors for other files.
#include "core/npy.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include <gtest/gtest.h>

#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

namespace fs = std::filesystem;

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), {}};
}

TEST(Npy, WritesTheFormatsBytes) {
  const fs::path dir = test::output_dir("npy_bytes");
  const float v[6] = {1.0f, -2.5f, std::numeric_limits<float>::quiet_NaN(), 0.0f, 3e-8f, 1e30f};
  ASSERT_TRUE(write_npy_f32((dir / "a.npy").string(), {2, 3}, v));
  const std::string b = slurp(dir / "a.npy");
  ASSERT_GE(b.size(), 10u);
  EXPECT_EQ(b.substr(0, 6), std::string("\x93NUMPY", 6));
  EXPECT_EQ(b[6], 1);
  EXPECT_EQ(b[7], 0);
  const std::size_t header_len = static_cast<unsigned char>(b[8]) | static_cast<unsigned char>(b[9]) << 8;
  EXPECT_EQ((10 + header_len) % 64, 0u) << "the data starts 64-byte aligned";
  const std::string header = b.substr(10, header_len);
  EXPECT_EQ(header.rfind("{'descr': '<f4', 'fortran_order': False, 'shape': (2,3), }", 0), 0u) << header;
  EXPECT_EQ(header.back(), '\n');
  ASSERT_EQ(b.size(), 10 + header_len + 24);
  float back[6];
  std::memcpy(back, b.data() + 10 + header_len, 24);
  EXPECT_EQ(back[1], -2.5f);
  EXPECT_TRUE(std::isnan(back[2]));
  EXPECT_EQ(back[5], 1e30f);
}

TEST(Npy, RoundTripsEveryShape) {
  const fs::path dir = test::output_dir("npy_round_trip");
  std::vector<float> v(4 * 5 * 2);
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = static_cast<float>(i) * 0.25f - 3.0f;
  for (const std::vector<std::int64_t>& shape :
       std::vector<std::vector<std::int64_t>>{{40}, {8, 5}, {4, 5, 2}, {0, 3}}) {
    const std::string path = (dir / ("s" + std::to_string(shape.size()) + ".npy")).string();
    ASSERT_TRUE(write_npy_f32(path, shape, v.data()));
    auto a = read_npy_f32(path);
    ASSERT_TRUE(a) << a.error().message;
    EXPECT_EQ(a->shape, shape);
    std::size_t n = 1;
    for (auto d : shape) n *= static_cast<std::size_t>(d);
    ASSERT_EQ(a->values.size(), n);
    for (std::size_t i = 0; i < n; ++i) EXPECT_EQ(a->values[i], v[i]);
  }
  // One dimension is written as NumPy writes it, "(40,)".
  EXPECT_NE(slurp(dir / "s1.npy").find("'shape': (40,)"), std::string::npos);
}

TEST(Npy, OtherFilesAreClearErrors) {
  const fs::path dir = test::output_dir("npy_errors");
  auto write = [&](const std::string& name, const std::string& bytes) {
    std::ofstream(dir / name, std::ios::binary) << bytes;
    return (dir / name).string();
  };
  auto header = [](const std::string& dict) {
    std::string h = dict;
    h.append((64 - (10 + h.size() + 1) % 64) % 64, ' ');
    h += '\n';
    return std::string("\x93NUMPY\x01\x00", 8) + static_cast<char>(h.size() & 0xFF) +
           static_cast<char>(h.size() >> 8) + h;
  };
  struct Case {
    std::string name, bytes, expected;
  } cases[] = {
      {"png.npy", "\x89PNG\r\n\x1a\n....", "not a .npy file"},
      {"f8.npy", header("{'descr': '<f8', 'fortran_order': False, 'shape': (2,), }") + std::string(16, '\0'),
       "dtype '<f8'"},
      {"fortran.npy",
       header("{'descr': '<f4', 'fortran_order': True, 'shape': (2,2), }") + std::string(16, '\0'),
       "fortran_order True"},
      {"short.npy",
       header("{'descr': '<f4', 'fortran_order': False, 'shape': (100,), }") + std::string(16, '\0'),
       "100 float32 values announced"},
      {"huge.npy", header("{'descr': '<f4', 'fortran_order': False, 'shape': (99999999,99999999), }"),
       "too large"},
      {"cut.npy", std::string("\x93NUMPY\x01\x00\x40", 9), "truncated header"},
  };
  for (const Case& c : cases) {
    auto a = read_npy_f32(write(c.name, c.bytes));
    ASSERT_FALSE(a) << c.name;
    EXPECT_NE(a.error().message.find(c.name), std::string::npos) << a.error().message;
    EXPECT_NE(a.error().message.find(c.expected), std::string::npos) << a.error().message;
  }
  EXPECT_FALSE(read_npy_f32((dir / "absent.npy").string()));
  EXPECT_FALSE(write_npy_f32((dir / "no" / "such" / "dir.npy").string(), {1}, nullptr));
}

}  // namespace
}  // namespace augrig
