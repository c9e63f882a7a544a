#include "core/npy.hpp"

#include <bit>
#include <cstring>
#include <fstream>
#include <numeric>

namespace augrig {
namespace {

constexpr char kMagic[] = "\x93NUMPY";  // 6 bytes, then the version's two bytes

std::string shape_text(const std::vector<std::int64_t>& shape) {
  std::string s = "(";
  for (std::size_t i = 0; i < shape.size(); ++i)
    s += std::to_string(shape[i]) + (shape.size() == 1 || i + 1 < shape.size() ? "," : "");
  return s + ")";
}

}  // namespace

Status write_npy_f32(const std::string& path, const std::vector<std::int64_t>& shape, const float* values) {
  static_assert(std::endian::native == std::endian::little,
                "the .npy writer stores '<f4' as it is in memory");
  std::int64_t n = 1;
  for (std::int64_t d : shape) {
    if (d < 0) return make_error(path, ": negative dimension in shape ", shape_text(shape));
    n *= d;
  }
  // The header: a Python dict literal padded with spaces so that the data starts at a multiple of
  // 64 bytes, ending with a newline (format 1.0: its length in 2 bytes).
  std::string header = "{'descr': '<f4', 'fortran_order': False, 'shape': " + shape_text(shape) + ", }";
  const std::size_t unpadded = 6 + 2 + 2 + header.size() + 1;
  header.append((64 - unpadded % 64) % 64, ' ');
  header += '\n';
  std::ofstream f(path, std::ios::binary);
  if (!f) return make_error(path, ": cannot create the file");
  const unsigned char version[2] = {1, 0};
  const std::uint16_t len = static_cast<std::uint16_t>(header.size());
  const unsigned char len_le[2] = {static_cast<unsigned char>(len & 0xFF),
                                   static_cast<unsigned char>(len >> 8)};
  f.write(kMagic, 6);
  f.write(reinterpret_cast<const char*>(version), 2);
  f.write(reinterpret_cast<const char*>(len_le), 2);
  f.write(header.data(), static_cast<std::streamsize>(header.size()));
  f.write(reinterpret_cast<const char*>(values), static_cast<std::streamsize>(n * 4));
  f.close();
  if (!f) return make_error(path, ": write failed");
  return {};
}

Expected<NpyArray> read_npy_f32(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return make_error(path, ": cannot open the file");
  char pre[8];
  if (!f.read(pre, 8) || std::memcmp(pre, kMagic, 6) != 0)
    return make_error(path, ": not a .npy file (expected the magic \\x93NUMPY)");
  const int major = static_cast<unsigned char>(pre[6]);
  std::size_t header_len = 0;
  if (major == 1) {
    unsigned char b[2];
    if (!f.read(reinterpret_cast<char*>(b), 2)) return make_error(path, ": truncated header");
    header_len = b[0] | static_cast<std::size_t>(b[1]) << 8;
  } else if (major == 2 || major == 3) {
    unsigned char b[4];
    if (!f.read(reinterpret_cast<char*>(b), 4)) return make_error(path, ": truncated header");
    header_len = b[0] | static_cast<std::size_t>(b[1]) << 8 | static_cast<std::size_t>(b[2]) << 16 |
                 static_cast<std::size_t>(b[3]) << 24;
  } else {
    return make_error(path, ": .npy format version ", major, " (expected 1, 2 or 3)");
  }
  if (header_len > (1u << 20))
    return make_error(path, ": header of ", header_len, " bytes (expected < 1 MiB)");
  std::string header(header_len, '\0');
  if (!f.read(header.data(), static_cast<std::streamsize>(header_len)))
    return make_error(path, ": truncated header");
  auto value_of = [&](const std::string& key) -> std::string {
    const std::size_t k = header.find("'" + key + "'");
    if (k == std::string::npos) return {};
    std::size_t v = header.find(':', k);
    if (v == std::string::npos) return {};
    ++v;
    while (v < header.size() && header[v] == ' ') ++v;
    if (v < header.size() && header[v] == '(') return header.substr(v, header.find(')', v) - v + 1);
    const std::size_t end = header.find_first_of(",}", v);
    return header.substr(v, end == std::string::npos ? std::string::npos : end - v);
  };
  if (const std::string d = value_of("descr"); d != "'<f4'")
    return make_error(path, ": dtype ", d.empty() ? "missing" : d,
                      " (expected '<f4', little-endian float32)");
  if (const std::string o = value_of("fortran_order"); o != "False")
    return make_error(path, ": fortran_order ", o.empty() ? "missing" : o, " (expected False, C order)");
  const std::string s = value_of("shape");
  if (s.size() < 2 || s.front() != '(') return make_error(path, ": shape missing (expected a tuple)");
  NpyArray a;
  std::int64_t n = 1;
  for (std::size_t i = 1; i + 1 < s.size();) {
    while (i + 1 < s.size() && (s[i] == ' ' || s[i] == ',')) ++i;
    if (i + 1 >= s.size()) break;
    std::size_t used = 0;
    long long d = 0;
    try {
      d = std::stoll(s.substr(i), &used);
    } catch (const std::exception&) {
      return make_error(path, ": shape ", s, " (expected non-negative integers)");
    }
    if (d < 0 || used == 0) return make_error(path, ": shape ", s, " (expected non-negative integers)");
    if (d > 0 && n > (std::int64_t{1} << 40) / d) return make_error(path, ": shape ", s, " is too large");
    a.shape.push_back(d);
    n *= d;
    i += used;
  }
  a.values.resize(static_cast<std::size_t>(n));
  if (!f.read(reinterpret_cast<char*>(a.values.data()), static_cast<std::streamsize>(n * 4)))
    return make_error(path, ": ", n, " float32 values announced, the file holds fewer");
  return a;
}

}  // namespace augrig
