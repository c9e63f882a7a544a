#include "recorder/euroc.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <map>
#include <mutex>
#include <set>
#include <span>
#include <sstream>
#include <thread>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <yaml-cpp/yaml.h>
#include <zlib.h>

#include "core/csv.hpp"
#include "core/file_check.hpp"
#include "nav/gps_time.hpp"
#include "nav/imu_stream.hpp"
#include "nav/logs.hpp"
#include "recorder/nav_inputs.hpp"
#include "recorder/plot.hpp"
#include "recorder/record.hpp"
#include "render/ground_truth.hpp"

namespace augrig::recorder {

namespace fs = std::filesystem;

namespace {

constexpr std::string_view kEurocScheme = "euroc://";
constexpr const char* kCameraCsvHeader = "#timestamp [ns],filename";
constexpr const char* kImuCsvHeader =
    "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],a_RS_S_x [m s^-2],"
    "a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]";

std::string num(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);  // shortest text that reads back exactly
  return std::string(buf, r.ptr);
}

// "module::function(): rest" -> "rest".
std::string strip_function(const std::string& m) {
  const auto p = m.find("(): ");
  if (p != std::string::npos && p < 64 && m.find(' ') > p) return m.substr(p + 4);
  return m;
}

bool parse_i64(std::string_view s, std::int64_t& v) {
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  return r.ec == std::errc() && r.ptr == s.data() + s.size() && !s.empty();
}

bool parse_f64(std::string_view s, double& v) {
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  return r.ec == std::errc() && r.ptr == s.data() + s.size() && !s.empty() && std::isfinite(v);
}

Expected<Image> read_png(const fs::path& path, PixelFormat gray) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return make_error(path.string(), ": no such file");
  cv::Mat m;
  try {
    m = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    return make_error(path.string(), ": cannot decode the image (", e.what(), ")");
  }
  if (m.empty()) {
    return make_error(path.string(), ": cannot read the image (unreadable, corrupt or not an image)");
  }
  if (m.depth() != CV_8U) return make_error(path.string(), ": expected 8-bit samples");
  PixelFormat format;
  cv::Mat conv;
  switch (m.channels()) {
    case 1:
      format = gray;
      break;
    case 3:
      format = PixelFormat::kRGB8;
      cv::cvtColor(m, conv, cv::COLOR_BGR2RGB);
      m = conv;
      break;
    case 4:
      format = PixelFormat::kRGBA8;
      cv::cvtColor(m, conv, cv::COLOR_BGRA2RGBA);
      m = conv;
      break;
    default:
      return make_error(path.string(), ": has ", m.channels(), " channels; expected 1, 3 or 4");
  }
  Image im(m.cols, m.rows, format);
  const std::size_t row_bytes = static_cast<std::size_t>(m.cols) * bytes_per_pixel(format);
  for (int y = 0; y < m.rows; ++y) std::copy_n(m.ptr<std::uint8_t>(y), row_bytes, im.row(y));
  return im;
}

Status write_text(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  out.close();
  if (!out) return make_error(path.string(), ": cannot write the file");
  return {};
}

// A rotation's entries come from its quaternion (Pose), a few ulps off where they are exactly 0
// or +-1 (a camera looking straight aft: -0.9999999999999999, 1.7e-16): those are written exact.
double snap_unit(double v) {
  for (double u : {0.0, 1.0, -1.0})
    if (std::abs(v - u) < 1e-14) return u;
  return v;
}

std::string matrix_row_major(const Eigen::Matrix4d& T) {
  std::string s = "[";
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c)
      s += (r || c ? ", " : "") + num(r < 3 && c < 3 ? snap_unit(T(r, c)) : T(r, c));
  return s + "]";
}

// Median interval of increasing times -> Hz (0 when fewer than two).
double median_rate_hz(std::vector<TimestampNs> t) {
  std::sort(t.begin(), t.end());
  std::vector<TimestampNs> d;
  for (std::size_t i = 1; i < t.size(); ++i)
    if (t[i] > t[i - 1]) d.push_back(t[i] - t[i - 1]);
  if (d.empty()) return 0;
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  const double hz = 1e9 / static_cast<double>(d[d.size() / 2]);
  return std::round(hz * 1000.0) / 1000.0;
}

// ---- PNG ------------------------------------------------------------------------------------------
// A PNG writer of its own, on zlib, because the export's cost is PNG encoding (bench/bench_export):
// OpenCV's writer tries libpng's adaptive filters on every row and cannot reuse work between the raw
// and the augmented image. Rows go in bands of kBandRows, each band its own raw-deflate segment that
// ends byte-aligned (Z_SYNC_FLUSH) and refers to nothing before it (Huffman-only or stored coding,
// or a deflateReset per band). So an augmented
// image reuses the raw image's segments for every band whose rows it did not change, and only the
// bands the boom touches are compressed again. Filters: Sub (row-local, so a band depends on its own
// rows only) for images, Up for masks (whose rows repeat); none when stored.

constexpr int kBandRows = 32;

enum class PngKind { kImage, kMask };

struct PngBand {
  std::string bytes;  // raw deflate, byte-aligned, not final
  std::uint32_t adler = 1;
  std::size_t length = 0;  // filtered bytes in
};

struct PngImage {
  int width = 0, height = 0, channels = 1;
  std::vector<PngBand> bands;
};

class PngEncoder {
 public:
  PngEncoder(int compression, PngKind kind) : kind_(kind) {
    compression = std::clamp(compression, 0, 9);
    filter_ = compression == 0 ? 0 : kind == PngKind::kMask ? 2 : 1;
    const int strategy = compression != 1         ? Z_DEFAULT_STRATEGY
                         : kind == PngKind::kMask ? Z_RLE
                                                  : Z_HUFFMAN_ONLY;
    // A band may refer back into the one before unless each starts a fresh stream; that matters
    // only where bands are swapped (images) and the coding has back-references (not Huffman-only,
    // not stored). Resetting costs a clear of the hash table per band.
    reset_each_band_ = kind == PngKind::kImage && compression >= 2;
    ok_ = deflateInit2(&z_, compression == 0 ? 0 : compression, Z_DEFLATED, -15, 8, strategy) == Z_OK;
  }
  ~PngEncoder() {
    if (ok_) deflateEnd(&z_);
  }
  PngEncoder(const PngEncoder&) = delete;
  PngEncoder& operator=(const PngEncoder&) = delete;

  // Encodes `image`; with `reuse` (an encoding of an image of the same size, format and kind), the
  // bands whose rows equal `reuse_pixels`'s are taken from it rather than compressed again.
  Expected<PngImage> encode(const Image& image, const PngImage* reuse = nullptr,
                            const Image* reuse_pixels = nullptr) {
    if (!ok_) return make_error("zlib: deflateInit2 failed");
    PngImage out;
    out.width = image.width();
    out.height = image.height();
    out.channels = bytes_per_pixel(image.format());
    const std::size_t row_bytes =
        static_cast<std::size_t>(out.width) * static_cast<std::size_t>(out.channels);
    const int bands = (out.height + kBandRows - 1) / kBandRows;
    out.bands.resize(static_cast<std::size_t>(bands));
    const bool can_reuse = kind_ == PngKind::kImage && reuse && reuse_pixels && reuse->width == out.width &&
                           reuse->height == out.height && reuse->channels == out.channels &&
                           reuse->bands.size() == out.bands.size() && reuse_pixels->width() == out.width &&
                           reuse_pixels->height() == out.height;
    for (int b = 0; b < bands; ++b) {
      const int y0 = b * kBandRows, y1 = std::min(out.height, y0 + kBandRows);
      if (can_reuse) {
        bool same = true;
        for (int y = y0; y < y1 && same; ++y)
          same = std::memcmp(image.row(y), reuse_pixels->row(y), row_bytes) == 0;
        // Up reaches into the row above the band: that row must be the same too.
        if (same && filter_ == 2 && y0 > 0)
          same = std::memcmp(image.row(y0 - 1), reuse_pixels->row(y0 - 1), row_bytes) == 0;
        if (same) {
          out.bands[static_cast<std::size_t>(b)] = reuse->bands[static_cast<std::size_t>(b)];
          continue;
        }
      }
      filtered_.resize(static_cast<std::size_t>(y1 - y0) * (row_bytes + 1));
      std::uint8_t* o = filtered_.data();
      for (int y = y0; y < y1; ++y) {
        const std::uint8_t* r = image.row(y);
        *o++ = static_cast<std::uint8_t>(filter_);
        if (filter_ == 1) {
          const std::size_t bpp = static_cast<std::size_t>(out.channels);
          std::memcpy(o, r, bpp);
          for (std::size_t x = bpp; x < row_bytes; ++x) o[x] = static_cast<std::uint8_t>(r[x] - r[x - bpp]);
        } else if (filter_ == 2 && y > 0) {
          const std::uint8_t* u = image.row(y - 1);
          for (std::size_t x = 0; x < row_bytes; ++x) o[x] = static_cast<std::uint8_t>(r[x] - u[x]);
        } else {
          std::memcpy(o, r, row_bytes);
        }
        o += row_bytes;
      }
      PngBand& band = out.bands[static_cast<std::size_t>(b)];
      band.length = filtered_.size();
      band.adler =
          static_cast<std::uint32_t>(adler32(1L, filtered_.data(), static_cast<uInt>(filtered_.size())));
      if ((b == 0 || reset_each_band_) && deflateReset(&z_) != Z_OK)
        return make_error("zlib: deflateReset failed");
      band.bytes.resize(deflateBound(&z_, static_cast<uLong>(filtered_.size())) + 64);
      z_.next_in = filtered_.data();
      z_.avail_in = static_cast<uInt>(filtered_.size());
      z_.next_out = reinterpret_cast<Bytef*>(band.bytes.data());
      z_.avail_out = static_cast<uInt>(band.bytes.size());
      const int rc = deflate(&z_, Z_SYNC_FLUSH);
      if (rc != Z_OK || z_.avail_in != 0) return make_error("zlib: deflate failed (", rc, ")");
      band.bytes.resize(band.bytes.size() - z_.avail_out);
    }
    return out;
  }

 private:
  PngKind kind_;
  int filter_ = 1;
  bool reset_each_band_ = false;
  z_stream z_{};
  bool ok_ = false;
  std::vector<std::uint8_t> filtered_;
};

void put_u32(std::string& s, std::uint32_t v) {
  const char b[4] = {static_cast<char>(v >> 24), static_cast<char>(v >> 16), static_cast<char>(v >> 8),
                     static_cast<char>(v)};
  s.append(b, 4);
}

void put_chunk(std::string& file, const char* type, const std::string& data) {
  put_u32(file, static_cast<std::uint32_t>(data.size()));
  const std::size_t start = file.size();
  file.append(type, 4);
  file += data;
  put_u32(file, static_cast<std::uint32_t>(crc32(0L, reinterpret_cast<const Bytef*>(file.data() + start),
                                                 static_cast<uInt>(file.size() - start))));
}

// The PNG file: signature, IHDR (8-bit gray, RGB or RGBA), IDAT (a zlib stream: header, the bands,
// an empty final block, the Adler-32 of every filtered byte), IEND.
std::string png_file(const PngImage& im) {
  std::string ihdr;
  put_u32(ihdr, static_cast<std::uint32_t>(im.width));
  put_u32(ihdr, static_cast<std::uint32_t>(im.height));
  const char colour = im.channels == 3 ? 2 : im.channels == 4 ? 6 : 0;
  ihdr += std::string{8, colour, 0, 0, 0};  // depth 8, colour type, deflate, adaptive filters, no interlace
  std::string idat = "\x78\x01";            // zlib header: deflate, 32 KiB window, fastest
  std::uint32_t adler = 1;
  for (const PngBand& b : im.bands) {
    idat += b.bytes;
    adler = static_cast<std::uint32_t>(adler32_combine(adler, b.adler, static_cast<z_off_t>(b.length)));
  }
  idat += std::string("\x03\x00", 2);  // final block, fixed Huffman codes, end of block at once
  put_u32(idat, adler);
  std::string file("\x89PNG\r\n\x1a\n", 8);
  file.reserve(idat.size() + 64);
  put_chunk(file, "IHDR", ihdr);
  put_chunk(file, "IDAT", idat);
  put_chunk(file, "IEND", {});
  return file;
}

Status write_file(const fs::path& path, const std::string& bytes) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return make_error(path.string(), ": cannot create the file (", std::strerror(errno), ")");
  const bool ok = std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
  const int err = errno;
  if (std::fclose(f) != 0 || !ok)
    return make_error(path.string(), ": cannot write the file (", std::strerror(ok ? errno : err), ")");
  return {};
}

// ---- The export's clock ---------------------------------------------------------------------------

// The lower envelope of d(x) (d = a later clock minus an earlier one, both stamping the same
// events with delays >= 0): the minimum of each 10 s window of x, linear between the windows'
// middles, constant beyond. The minimum takes the least-delayed event; windows follow a drift.
class LowerEnvelope {
 public:
  void add(TimestampNs x, TimestampNs d) { points_.emplace_back(x, d); }
  bool empty() const { return points_.empty(); }
  std::size_t size() const { return points_.size(); }
  void finish() {
    std::sort(points_.begin(), points_.end());
    knots_.clear();
    constexpr TimestampNs kWindowNs = 10'000'000'000;
    for (std::size_t i = 0; i < points_.size();) {
      const TimestampNs start = points_[i].first;
      TimestampNs lo = points_[i].second, last = start;
      for (; i < points_.size() && points_[i].first < start + kWindowNs; ++i) {
        lo = std::min(lo, points_[i].second);
        last = points_[i].first;
      }
      knots_.emplace_back(start + (last - start) / 2, lo);
    }
  }
  TimestampNs at(TimestampNs x) const {
    if (knots_.empty()) return 0;
    if (x <= knots_.front().first) return knots_.front().second;
    if (x >= knots_.back().first) return knots_.back().second;
    const auto it =
        std::upper_bound(knots_.begin(), knots_.end(), std::pair{x, std::numeric_limits<TimestampNs>::min()});
    const auto& [x1, d1] = *it;
    const auto& [x0, d0] = *(it - 1);
    const double f = static_cast<double>(x - x0) / static_cast<double>(x1 - x0);
    return d0 + static_cast<TimestampNs>(std::llround(f * static_cast<double>(d1 - d0)));
  }

 private:
  std::vector<std::pair<TimestampNs, TimestampNs>> points_, knots_;
};

// Each camera's frame time (its recorded clock, with its host arrival) -> the export's clock.
struct ExportClock {
  ClockDomain clock = ClockDomain::kUnknown;
  std::string note;
  enum class Mode { kIdentity, kConstant, kThroughHost } mode = Mode::kIdentity;
  TimestampNs constant_ns[2] = {0, 0};  // kConstant: t - constant
  LowerEnvelope device_to_host[2];      // host - device, per camera (kThroughHost)
  bool frames_on_host = false;
  LowerEnvelope host_to_gps;  // host arrival - GPS time (kThroughHost)

  TimestampNs map(int camera, TimestampNs t_ns) const {
    switch (mode) {
      case Mode::kIdentity:
        return t_ns;
      case Mode::kConstant:
        return t_ns - constant_ns[camera];
      case Mode::kThroughHost: {
        const TimestampNs host = frames_on_host ? t_ns : t_ns + device_to_host[camera].at(t_ns);
        const TimestampNs guess = host - host_to_gps.at(std::numeric_limits<TimestampNs>::max());
        return host - host_to_gps.at(guess);
      }
    }
    return t_ns;
  }
};

// "offsets to gps A, B ns" in the recording's clock_domains meta (augrig demo writes it).
std::optional<std::array<TimestampNs, 2>> stated_gps_offsets(const std::string& clock_domains) {
  const std::string key = "offsets to gps ";
  const auto p = clock_domains.find(key);
  if (p == std::string::npos) return std::nullopt;
  std::array<TimestampNs, 2> o{};
  const char* s = clock_domains.data() + p + key.size();
  const char* end = clock_domains.data() + clock_domains.size();
  auto r = std::from_chars(s, end, o[0]);
  if (r.ec != std::errc() || r.ptr + 2 > end || r.ptr[0] != ',' || r.ptr[1] != ' ') return std::nullopt;
  r = std::from_chars(r.ptr + 2, end, o[1]);
  if (r.ec != std::errc()) return std::nullopt;
  return o;
}

// "clock_offset camera=left t_device_ns=... offset_ns=..." events (augrig run): host - device.
void add_clock_offset_events(const std::vector<EventRecord>& events, LowerEnvelope (&device_to_host)[2]) {
  for (const EventRecord& e : events) {
    if (e.text.rfind("clock_offset ", 0) != 0) continue;
    auto field = [&](const std::string& k) -> std::string {
      const auto p = e.text.find(" " + k + "=");
      if (p == std::string::npos) return {};
      const auto v = p + k.size() + 2;
      return e.text.substr(v, e.text.find(' ', v) - v);
    };
    const std::string cam = field("camera");
    TimestampNs t = 0, off = 0;
    if ((cam != "left" && cam != "right") || !parse_i64(field("t_device_ns"), t) ||
        !parse_i64(field("offset_ns"), off))
      continue;
    device_to_host[cam == "left" ? 0 : 1].add(t, off);
  }
}

// ---- Nav inputs -------------------------------------------------------------------------------------

// A stream's IMU samples: augrig IMU datagrams (BLOB rows, as `augrig run --nav` records them) or
// recorder::imu_input() CSV rows; sorted by t_ns, repeats dropped. arrival_ns: the row's.
struct ImuStreamData {
  std::vector<nav::ImuSample> samples;
  ClockDomain clock = ClockDomain::kGps;
  std::size_t undecodable = 0, repeats = 0;
  std::string first_error;
};

Expected<ImuStreamData> imu_stream_data(const std::vector<const NavInputRecord*>& rows,
                                        const std::string& name) {
  ImuStreamData out;
  std::string text;
  bool any_text = false, any_binary = false;
  for (const NavInputRecord* r : rows) {
    if (!r->binary) {
      text += r->data + "\n";
      any_text = true;
      continue;
    }
    any_binary = true;
    auto d = nav::decode_imu_datagram(
        std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(r->data.data()), r->data.size()));
    if (!d) {
      if (out.undecodable++ == 0) out.first_error = d.error().message;
      continue;
    }
    out.clock = d->clock;
    for (nav::ImuSample s : d->samples) {
      s.arrival_ns = r->arrival_ns;
      out.samples.push_back(s);
    }
  }
  if (any_text) {
    std::istringstream in(std::string(imu_input_header()) + "\n" + text);
    auto log = nav::parse_imu_csv(in, name);
    if (!log) return log.error();
    if (!any_binary) out.clock = log->clock;
    out.repeats += log->issues.out_of_order + log->issues.duplicates;
    out.samples.insert(out.samples.end(), log->samples.begin(), log->samples.end());
  }
  std::stable_sort(out.samples.begin(), out.samples.end(),
                   [](const nav::ImuSample& a, const nav::ImuSample& b) { return a.t_ns < b.t_ns; });
  std::vector<nav::ImuSample> kept;
  kept.reserve(out.samples.size());
  for (const nav::ImuSample& s : out.samples) {
    if (!kept.empty() && s.t_ns <= kept.back().t_ns) {
      ++out.repeats;  // a datagram sent or received twice
      continue;
    }
    kept.push_back(s);
  }
  out.samples = std::move(kept);
  return out;
}

bool is_nmea_line(const std::string& s) {
  return !s.empty() && (s.front() == '$' || s.front() == '!');
}

// Reads sensor.yaml's optional `augrig:` keys, ignoring a missing or unreadable file. A directory
// there is an error: it would open and read as an empty file, silently.
Status read_augrig_keys(const fs::path& yaml, std::optional<PixelFormat>& format,
                        std::optional<ClockDomain>& clock) {
  if (auto d = check_not_directory("", yaml.string()); !d) return d;
  std::ifstream in(yaml, std::ios::binary);
  if (!in) return {};
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (text.rfind("%YAML:", 0) == 0)
    text = text.substr(std::min(text.size(), text.find('\n')));  // OpenCV's header
  try {
    const YAML::Node root = YAML::Load(text);
    const YAML::Node a = root["augrig"];
    if (!a || !a.IsMap()) return {};
    PixelFormat f;
    if (a["pixel_format"] && parse_pixel_format(a["pixel_format"].as<std::string>(), f)) format = f;
    ClockDomain c;
    if (a["clock"] && parse_clock_domain(a["clock"].as<std::string>(), c)) clock = c;
  } catch (const std::exception&) {
  }
  return {};
}

}  // namespace

// ---- Export -----------------------------------------------------------------------------------------

std::string euroc_camera_yaml(const RigCamera& camera, const std::string& side, const std::string& stream,
                              double rate_hz, PixelFormat format, ClockDomain clock) {
  const CameraModel& m = camera.model;
  std::string model = "radial-tangential";
  std::vector<double> coeffs = {0, 0, 0, 0};
  if (m.distortion == DistortionModel::kRadTan) {
    coeffs = {m.coeffs[0], m.coeffs[1], m.coeffs[2], m.coeffs[3]};
    if (m.coeffs[4] != 0) coeffs.push_back(m.coeffs[4]);  // k3: OpenCV's fifth coefficient
  } else if (m.distortion == DistortionModel::kEquidistant) {
    model = "equidistant";
    coeffs = {m.coeffs[0], m.coeffs[1], m.coeffs[2], m.coeffs[3]};
  }
  std::string c = "[";
  for (std::size_t i = 0; i < coeffs.size(); ++i) c += (i ? ", " : "") + num(coeffs[i]);
  c += "]";
  std::ostringstream o;
  o << "# augrig export: the " << side << " camera ('" << camera.name << "'), " << stream << " images.\n"
    << "# T_BS: sensor S = the camera's OpenCV frame (x right, y down, z along the optical axis) in the\n"
    << "# body frame B = the tanker body frame (FRD: x forward, y right, z down): p_B = T_BS * p_S,\n"
    << "# 4x4, row-major, metres. Pixel (0, 0) is the centre of the top-left pixel.\n"
    << "sensor_type: camera\n"
    << "comment: \"augrig " << side << " camera, " << stream << "\"\n"
    << "T_BS:\n  cols: 4\n  rows: 4\n  data: " << matrix_row_major(camera.T_body_cam.matrix()) << "\n"
    << "rate_hz: " << num(rate_hz) << "\n"
    << "resolution: [" << m.width_px << ", " << m.height_px << "]\n"
    << "camera_model: pinhole\n"
    << "intrinsics: [" << num(m.fx_px) << ", " << num(m.fy_px) << ", " << num(m.cx_px) << ", " << num(m.cy_px)
    << "]  # fu, fv, cu, cv\n"
    << "distortion_model: " << model << "\n"
    << "distortion_coefficients: " << c
    << (model == "equidistant" ? "  # k1, k2, k3, k4"
        : coeffs.size() == 5   ? "  # k1, k2, p1, p2, k3"
                               : "  # k1, k2, p1, p2")
    << "\n"
    << "# How the PNGs decode: a Bayer mosaic is stored as 8-bit gray, the pattern is pixel_format.\n"
    << "augrig:\n  stream: " << stream << "\n  pixel_format: " << to_string(format)
    << "\n  clock: " << to_string(clock) << "\n  near_m: " << num(camera.near_m)
    << "\n  far_m: " << num(camera.far_m) << "\n";
  return o.str();
}

namespace {

// One output image stream: mav0/<name>/data/<t_ns>.png and data.csv.
struct StreamOut {
  fs::path dir;
  std::string csv;  // data.csv's text, in frame order
  std::set<TimestampNs> seen;
  std::size_t written = 0;
  PixelFormat format = PixelFormat::kMono8;
  ClockDomain clock = ClockDomain::kUnknown;
  int width = 0, height = 0;
  bool created = false;
};

constexpr const char* kStreamSuffix[3] = {"", "_augmented", "_mask"};

// The ground truth streams (EurocExportOptions::ground_truth), each a folder of mav0/ with data/
// and data.csv: per camera the depth (.npy) and its 16-bit mm PNG; for the left camera the
// correspondence into the right image (.npy) and the stereo classes (PNG).
enum GtStream { kGtDepth0, kGtDepth1, kGtDepthMm0, kGtDepthMm1, kGtRightPx, kGtStereoClass, kGtStreams };
constexpr const char* kGtFolder[kGtStreams] = {"cam0_depth",    "cam1_depth",    "cam0_depth_mm",
                                               "cam1_depth_mm", "cam0_right_px", "cam0_stereo_class"};
constexpr const char* kGtExt[kGtStreams] = {".npy", ".npy", ".png", ".png", ".npy", ".png"};
constexpr int kGtCamera[kGtStreams] = {0, 1, 0, 1, 0, 0};  // whose timestamp names the file
constexpr const char* kGtContent[kGtStreams] = {
    "receiver depth, float32 H x W .npy, metres along the optical axis (z), NaN where no receiver",
    "receiver depth, float32 H x W .npy, metres along the optical axis (z), NaN where no receiver",
    "receiver depth, 16-bit PNG, round(z * 1000) mm, 0 where no receiver, 65535 = 65.535 m or more",
    "receiver depth, 16-bit PNG, round(z * 1000) mm, 0 where no receiver, 65535 = 65.535 m or more",
    ("float32 H x W x 2 .npy: (u, v) in the right raw image of each left receiver pixel's surface point, NaN "
     "where none"),
    "8-bit PNG: stereo class per left pixel, 0 no receiver, 1 both, 2 left only, 3 right only, 4 neither"};

// The work of one camera of one frame: its raw, augmented and mask images encoded and written; or
// (camera kGroundTruthJob) the frame's ground truth, made from its depth, masks and the rig.
constexpr int kGroundTruthJob = 2;
struct CameraJob {
  std::shared_ptr<const FrameRecord> rec;
  int camera = 0;
  fs::path files[3];  // empty: not written
  const Rig* rig = nullptr;
  fs::path gt_files[kGtStreams];  // kGroundTruthJob; empty: not written
};

// What docs/GROUND_TRUTH.md's files beside a frame's images hold, from what a recording keeps:
// the depth as recorded, the correspondence (render/ground_truth.hpp) and the stereo classes
// (render/stats.hpp, the augmenter's own test) from the depth, the masks and the rig.
Status run_ground_truth_job(const CameraJob& job) {
  const FrameRecord& r = *job.rec;
  const Rig& rig = *job.rig;
  const DepthImage depth[2] = {r.receiver_depth[0].image(), r.receiver_depth[1].image()};
  for (int c = 0; c < 2; ++c) {
    if (!job.gt_files[kGtDepth0 + c].empty())
      if (Status s = write_depth_npy(job.gt_files[kGtDepth0 + c].string(), depth[c]); !s) return s;
    if (!job.gt_files[kGtDepthMm0 + c].empty())
      if (Status s = write_depth_mm_png(job.gt_files[kGtDepthMm0 + c].string(), depth[c]); !s) return s;
  }
  const CameraModel& left = rig.cameras[0].model;
  const CameraModel& right = rig.cameras[1].model;
  const Pose T_right_left = rig.T_right_left();
  const int w = depth[0].width, h = depth[0].height;
  if (!job.gt_files[kGtRightPx].empty())
    if (Status s = write_correspondence_npy(job.gt_files[kGtRightPx].string(),
                                            right_correspondence(depth[0], left, right, T_right_left), w, h);
        !s)
      return s;
  if (!job.gt_files[kGtStereoClass].empty()) {
    std::vector<std::uint8_t> classes;
    StereoClassOptions o;  // the augmenter's defaults, as every command runs it
    (void)compute_occlusion_stats(0, r.mask[0], r.mask[1], depth[0], depth[1], left, right, T_right_left, o,
                                  &classes);
    if (Status s = write_stereo_class_png(job.gt_files[kGtStereoClass].string(), classes, w, h); !s) return s;
  }
  return {};
}

struct Encoders {
  PngEncoder image, mask;
  explicit Encoders(int compression)
      : image(compression, PngKind::kImage), mask(compression, PngKind::kMask) {}
};

Status run_camera_job(const CameraJob& job, Encoders& enc) {
  if (job.camera == kGroundTruthJob) return run_ground_truth_job(job);
  const int c = job.camera;
  const Image* images[3] = {&job.rec->raw[static_cast<CameraId>(c)].image, &job.rec->augmented[c],
                            &job.rec->mask[c]};
  std::optional<PngImage> raw_png;
  for (int k = 0; k < 3; ++k) {
    if (job.files[k].empty()) continue;
    // The raw encoding is kept for the augmented image, which equals it outside the boom's rows.
    auto png = k == 2   ? enc.mask.encode(*images[k])
               : k == 1 ? enc.image.encode(*images[k], raw_png ? &*raw_png : nullptr, images[0])
                        : enc.image.encode(*images[k]);
    if (!png) return make_error(job.files[k].string(), ": ", png.error().message);
    if (auto s = write_file(job.files[k], png_file(*png)); !s) return s;
    if (k == 0 && !job.files[1].empty()) raw_png = std::move(*png);
  }
  return {};
}

// A bounded pool: push() waits while `capacity` jobs are queued; results are kept by frame.
class JobPool {
 public:
  JobPool(int threads, int compression, std::size_t capacity) : capacity_(capacity) {
    for (int t = 0; t < threads; ++t)
      workers_.emplace_back([this, compression] {
        Encoders enc(compression);
        for (;;) {
          std::pair<std::size_t, CameraJob> job;
          {
            std::unique_lock<std::mutex> lk(m_);
            cv_.wait(lk, [&] { return stop_ || !queue_.empty(); });
            if (queue_.empty()) return;
            job = std::move(queue_.front());
            queue_.pop_front();
          }
          cv_.notify_all();
          Status s = stop_ ? Status{} : run_camera_job(job.second, enc);
          job.second.rec.reset();  // the images go as soon as they are written
          {
            std::lock_guard<std::mutex> lk(m_);
            Done& d = done_[job.first];
            ++d.jobs;
            if (!s && d.status) d.status = s;
          }
          cv_.notify_all();
        }
      });
  }
  ~JobPool() { stop(); }
  void push(std::size_t frame, CameraJob job) {
    std::unique_lock<std::mutex> lk(m_);
    cv_.wait(lk, [&] { return queue_.size() < capacity_; });
    queue_.emplace_back(frame, std::move(job));
    cv_.notify_all();
  }
  // Waits (when `wait`) until `jobs` jobs of `frame` are done; their status, or nullopt when not yet.
  std::optional<Status> take(std::size_t frame, int jobs, bool wait) {
    std::unique_lock<std::mutex> lk(m_);
    auto ready = [&] {
      auto it = done_.find(frame);
      return it != done_.end() && it->second.jobs >= jobs;
    };
    if (wait)
      cv_.wait(lk, ready);
    else if (!ready())
      return std::nullopt;
    Status s = done_[frame].status;
    done_.erase(frame);
    return s;
  }
  void stop() {
    {
      std::lock_guard<std::mutex> lk(m_);
      stop_ = true;
    }
    cv_.notify_all();
    for (std::thread& t : workers_)
      if (t.joinable()) t.join();
    workers_.clear();
  }

 private:
  struct Done {
    int jobs = 0;
    Status status;
  };
  std::size_t capacity_;
  std::mutex m_;
  std::condition_variable cv_;
  std::deque<std::pair<std::size_t, CameraJob>> queue_;
  std::map<std::size_t, Done> done_;
  bool stop_ = false;
  std::vector<std::thread> workers_;
};

// Per frame, what the export writes once its images are on disk (in frame order).
struct PendingFrame {
  std::size_t index = 0;
  int jobs = 0;
  bool readable = false;
  TimestampNs t_ns[2] = {0, 0};  // on the export's clock
  bool write[3][2] = {};
  bool write_gt[kGtStreams] = {};
  std::uint64_t sequence[2] = {0, 0};
};

struct GtStreamOut {
  fs::path dir;
  std::string csv;
  std::set<TimestampNs> seen;
  std::size_t written = 0;
  bool created = false;
};

// sensor.yaml of a ground truth stream: what its files hold, on which clock.
std::string ground_truth_yaml(int k, const RigCamera& camera, double rate_hz, ClockDomain clock) {
  std::string num_rate;
  {
    char buf[64];
    const auto r = std::to_chars(buf, buf + sizeof buf, rate_hz);
    num_rate.assign(buf, r.ptr);
  }
  std::ostringstream o;
  o << "# augrig export --ground-truth: " << kGtFolder[k] << " (docs/GROUND_TRUTH.md), the "
    << (kGtCamera[k] ? "right" : "left") << " camera ('" << camera.name << "'); pixels are its raw pixels.\n"
    << "sensor_type: ground_truth\n"
    << "comment: \"" << kGtContent[k] << "\"\n"
    << "rate_hz: " << num_rate << "\n"
    << "resolution: [" << camera.model.width_px << ", " << camera.model.height_px << "]\n"
    << "augrig:\n  stream: " << (std::string(kGtFolder[k]).substr(5)) << "\n  clock: " << to_string(clock)
    << "\n";
  return o.str();
}

void write_marker(const fs::path& marker, const std::string& recording, const std::string& out,
                  const std::vector<std::string>& lines) {
  std::ofstream m(marker, std::ios::binary);
  m << "augrig export " << recording << " -> " << out << " is incomplete";
  m << (lines.empty() ? ": it was still running or was stopped before the end\n" : ":\n");
  for (const std::string& l : lines) m << l << "\n";
}

std::string fmt_offset_ms(TimestampNs ns) {
  std::ostringstream o;
  o << std::fixed << std::setprecision(3) << static_cast<double>(ns) / 1e6 << " ms";
  return o.str();
}

}  // namespace

namespace {

// mav0/state_groundtruth_estimate0 in EuRoC's layout and columns, for the receiver: R (EuRoC's
// reference frame) is the tanker body frame (FRD), S the receiver body frame (FRD); p_RS_R and q_RS
// from the recorded T_body_receiver, v_RS_R by central differences of the positions (one-sided at
// the ends), the IMU biases 0 (augrig estimates none). sensor.yaml says so.
Status write_receiver_states(const fs::path& dir, const std::vector<std::pair<TimestampNs, Pose>>& states) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return make_error(dir.string(), ": cannot create the folder (", ec.message(), ")");
  std::string csv =
      "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z [], "
      "v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], b_w_RS_S_y [rad "
      "s^-1], "
      "b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], b_a_RS_S_z [m s^-2]\n";
  const std::size_t n = states.size();
  for (std::size_t i = 0; i < n; ++i) {
    const auto& [t, T] = states[i];
    const std::size_t a = i > 0 ? i - 1 : i, b = i + 1 < n ? i + 1 : i;
    Eigen::Vector3d v = Eigen::Vector3d::Zero();
    if (b != a && states[b].first != states[a].first)
      v = (states[b].second.translation_m - states[a].second.translation_m) /
          (static_cast<double>(states[b].first - states[a].first) * 1e-9);
    const Eigen::Quaterniond q = T.rotation.normalized();
    csv += std::to_string(t);
    for (double x : {T.translation_m.x(), T.translation_m.y(), T.translation_m.z(), q.w(), q.x(), q.y(),
                     q.z(), v.x(), v.y(), v.z()})
      csv += "," + num(x);
    csv += ",0,0,0,0,0,0\n";
  }
  if (auto s = write_text(dir / "data.csv", csv); !s) return s;
  return write_text(
      dir / "sensor.yaml",
      "# The receiver's pose relative to the tanker, as recorded (augrig export; docs/REPLAY.md).\n"
      "# EuRoC's columns: R = the tanker body frame (FRD: x forward, y right, z down), S = the receiver\n"
      "# body frame (FRD); p_RS_R the receiver's origin in R (m), q_RS its rotation (Hamilton, w first),\n"
      "# v_RS_R central differences of p_RS_R over the exported frames, biases 0: not estimated.\n"
      "# Timestamps: the left camera's (cam0) t_ns of each stereo frame, on the export's clock.\n"
      "sensor_type: groundtruth\ncomment: receiver pose relative to the tanker body frame\n");
}

// export --ground-truth of a frame recorded without its depth: which, and how to get it.
Error no_depth_error(const RecordingReader& reader, std::size_t i, std::uint64_t pair_sequence,
                     const std::string& how_many = "") {
  const fs::path db(reader.path());
  const std::string dir =
      db.filename() == "recording.sqlite" && db.has_parent_path() ? db.parent_path().string() : db.string();
  return make_error(reader.path(), ": frame ", i, " (pair_sequence ", pair_sequence,
                    ") holds no receiver depth", how_many,
                    ", and the ground truth is made from it: the recording was made without --ground-truth. "
                    "Store it by replaying the recording into a new one: augrig replay ",
                    dir, " --record NEW --ground-truth --headless; then export NEW --ground-truth");
}

Status export_body(const RecordingReader& reader, const fs::path& out, const EurocExportOptions& options,
                   const Rig& rig, EurocExportReport& report) {
  const std::string where = "recorder::export_euroc(): ";
  const fs::path mav0 = out / "mav0";
  std::error_code ec;
  const auto t_start = std::chrono::steady_clock::now();
  // The recording's own damage (a truncated file: frames its summary counts but no row holds).
  for (const std::string& p : reader.problems())
    report.problems.push_back(p.rfind(reader.path(), 0) == 0 ? p : reader.path() + ": " + p);

  const std::size_t n = reader.frame_count();
  report.frames = n;

  // Every frame's metadata first (no image): the rate, the clocks, the names.
  std::vector<std::optional<FrameRecord>> infos(n);
  bool all_gps = n > 0, all_device = n > 0, all_host = n > 0;
  {
    std::vector<TimestampNs> t;
    for (std::size_t i = 0; i < n; ++i) {
      auto info = reader.read_frame_info(i);
      if (!info) continue;
      t.push_back(info->raw.t_key_ns);
      for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
        const ClockDomain c = info->raw[id].clock;
        all_gps &= c == ClockDomain::kGps;
        all_device &= c == ClockDomain::kDevice;
        all_host &= c == ClockDomain::kHostMonotonic;
      }
      infos[i] = std::move(*info);
    }
    report.rate_hz = median_rate_hz(std::move(t));
  }

  // Nav inputs, by stream.
  auto inputs = reader.nav_inputs();
  std::map<std::string, std::vector<const NavInputRecord*>> by_stream;
  if (!inputs)
    report.problems.push_back(strip_function(inputs.error().message) + "; no nav input exported");
  else
    for (const NavInputRecord& r : *inputs) by_stream[r.stream].push_back(&r);

  // The clock (docs/REPLAY.md): GPS time when the frames can be put on it.
  ExportClock clk;
  if (all_gps) {
    clk.clock = ClockDomain::kGps;
    clk.note = "the frames were recorded in GPS time";
  } else if (const auto off = stated_gps_offsets(reader.meta("clock_domains")); off && all_device) {
    clk.mode = ExportClock::Mode::kConstant;
    clk.constant_ns[0] = (*off)[0];
    clk.constant_ns[1] = (*off)[1];
    clk.clock = ClockDomain::kGps;
    clk.note = "frames: device clock minus the camera offsets to GPS time the recording states (" +
               std::to_string((*off)[0]) + ", " + std::to_string((*off)[1]) + " ns)";
  } else if (all_device || all_host) {
    // Host arrival against GPS time of every nav input that says its time.
    NavInputStamper stamper;
    for (const auto& [name, rows] : by_stream)
      for (const NavInputRecord* r : rows) {
        if (r->arrival_ns == 0) continue;
        if (r->binary) {
          auto d = nav::decode_imu_datagram(std::span<const std::uint8_t>(
              reinterpret_cast<const std::uint8_t*>(r->data.data()), r->data.size()));
          if (d && d->clock == ClockDomain::kGps)
            for (const nav::ImuSample& s : d->samples) clk.host_to_gps.add(s.t_ns, r->arrival_ns - s.t_ns);
        } else if (is_nmea_line(r->data)) {
          NavInputRecord copy = *r;
          if (stamper.stamp(copy) == NavInputTimeSource::kNmeaTimeTag)
            clk.host_to_gps.add(copy.t_ns, r->arrival_ns - copy.t_ns);
        }
      }
    clk.frames_on_host = all_host;
    if (!all_host) {
      if (auto ev = reader.events()) add_clock_offset_events(*ev, clk.device_to_host);
      for (int c = 0; c < 2; ++c) {
        if (!clk.device_to_host[c].empty()) continue;
        for (const auto& info : infos)
          if (info && info->raw[static_cast<CameraId>(c)].t_host_ns != 0) {
            const Frame& f = info->raw[static_cast<CameraId>(c)];
            clk.device_to_host[c].add(f.t_ns, f.t_host_ns - f.t_ns);
          }
      }
    }
    const bool cameras_ok = all_host || (!clk.device_to_host[0].empty() && !clk.device_to_host[1].empty());
    if (!clk.host_to_gps.empty() && cameras_ok) {
      clk.host_to_gps.finish();
      for (auto& e : clk.device_to_host) e.finish();
      clk.mode = ExportClock::Mode::kThroughHost;
      clk.clock = ClockDomain::kGps;
      clk.note =
          std::string("frames: ") +
          (all_host
               ? "host CLOCK_MONOTONIC"
               : "each camera's device clock -> host CLOCK_MONOTONIC (lower envelope of t_host_ns - t_ns, or "
                 "the recording's clock_offset events)") +
          " -> GPS time (lower envelope of the nav inputs' host arrival minus their own time, " +
          std::to_string(clk.host_to_gps.size()) + " samples; host - GPS " +
          fmt_offset_ms(clk.host_to_gps.at(0)) + " at the start)";
    }
  }
  if (clk.clock == ClockDomain::kUnknown) {
    clk.clock = n && infos[0] ? infos[0]->raw.left.clock : ClockDomain::kUnknown;
    clk.note = "the frames' recorded clock (" + std::string(to_string(clk.clock)) +
               "): the recording gives no way to GPS time";
    if (!by_stream.empty())
      report.notes.push_back(
          "the frames could not be put on GPS time (no camera offsets and no nav input with "
          "both its own time and its host arrival): imu0 and the nav logs keep their own clock");
  }
  report.clock = clk.clock;
  report.clock_note = clk.note;

  // Names: each camera's frames on the export's clock; a repeated time is written once.
  StreamOut streams[3][2];
  for (int k = 0; k < 3; ++k)
    for (int c = 0; c < 2; ++c) streams[k][c].dir = mav0 / ("cam" + std::to_string(c) + kStreamSuffix[k]);
  unsigned parts = kPartRaw;
  if (options.augmented) parts |= kPartAugmented;
  if (options.masks) parts |= kPartMasks;
  // The ground truth needs the depth, and the masks for the stereo classes.
  if (options.ground_truth) parts |= kPartDepth | kPartMasks;
  GtStreamOut gt[kGtStreams];
  for (int k = 0; k < kGtStreams; ++k) gt[k].dir = mav0 / kGtFolder[k];

  int threads = options.threads;
  if (threads <= 0) threads = std::max(2, static_cast<int>(std::thread::hardware_concurrency()));
  std::unique_ptr<JobPool> pool;
  std::unique_ptr<Encoders> inline_enc;
  if (threads > 1)
    pool = std::make_unique<JobPool>(threads, options.png_compression, static_cast<std::size_t>(2 * threads));
  else
    inline_enc = std::make_unique<Encoders>(options.png_compression);

  std::vector<nav::CameraPoseRow> poses;
  // The receiver in the tanker body frame per stereo frame (at the left camera's time) for
  // mav0/state_groundtruth_estimate0.
  std::vector<std::pair<TimestampNs, Pose>> receiver_states;
  std::vector<OcclusionStats> stats;
  nav::FrameIndex index;
  index.clock = clk.clock;
  index.metadata["content"] = "the exported raw frames (augrig export); t_ns on the export's clock";
  std::int64_t max_skew_ns = 0;
  std::deque<PendingFrame> pending;
  std::size_t skipped = 0;
  bool no_class_noted = false;
  auto last_progress = std::chrono::steady_clock::now();
  auto progress = [&](bool final) {
    if (!options.progress) return;
    const auto now = std::chrono::steady_clock::now();
    if (!final && std::chrono::duration<double>(now - last_progress).count() < options.progress_interval_s)
      return;
    last_progress = now;
    EurocExportProgress p;
    p.frames_total = n;
    p.frames_written = report.frames_written;
    p.frames_skipped = skipped;
    p.frames_done = p.frames_written + p.frames_skipped;
    p.elapsed_s = std::chrono::duration<double>(now - t_start).count();
    p.frames_per_s = p.elapsed_s > 0 ? static_cast<double>(p.frames_done) / p.elapsed_s : 0;
    p.eta_s = p.frames_per_s > 0 ? static_cast<double>(n - p.frames_done) / p.frames_per_s : 0;
    p.final = final;
    options.progress(p);
  };
  // Frames whose images are written: their data.csv rows, in frame order.
  auto drain = [&](bool wait) -> Status {
    while (!pending.empty()) {
      PendingFrame& pf = pending.front();
      if (pf.jobs > 0 && pool) {
        auto s = pool->take(pf.index, pf.jobs, wait);
        if (!s) return {};
        if (!*s) return *s;
      }
      if (pf.readable) {
        for (int c = 0; c < 2; ++c)
          for (int k = 0; k < 3; ++k) {
            if (!pf.write[k][c]) continue;
            StreamOut& so = streams[k][c];
            const std::string name = std::to_string(pf.t_ns[c]) + ".png";
            so.csv += std::to_string(pf.t_ns[c]) + "," + name + "\n";
            ++so.written;
            if (k == 0) {
              nav::FrameIndexRow row;
              row.sequence = pf.sequence[c];
              row.camera = c;
              row.t_ns = pf.t_ns[c];
              row.file = "mav0/cam" + std::to_string(c) + "/data/" + name;
              index.rows.push_back(std::move(row));
            }
          }
        for (int k = 0; k < kGtStreams; ++k) {
          if (!pf.write_gt[k]) continue;
          const TimestampNs t = pf.t_ns[kGtCamera[k]];
          gt[k].csv += std::to_string(t) + "," + std::to_string(t) + kGtExt[k] + "\n";
          ++gt[k].written;
        }
        if (pf.write_gt[kGtDepth0] || pf.write_gt[kGtDepth1]) ++report.ground_truth_written;
        ++report.frames_written;
      } else {
        ++skipped;
      }
      pending.pop_front();
      progress(false);
    }
    return {};
  };
  auto fail = [&](Status s) -> Status {
    if (pool) pool->stop();
    return make_error(where, s.error().message);
  };

  for (std::size_t i = 0; i < n; ++i) {
    PendingFrame pf;
    pf.index = i;
    auto rec = reader.read_frame(i, parts);
    if (!rec) {
      report.problems.push_back(strip_function(rec.error().message) + "; frame not exported");
      pending.push_back(pf);
      if (auto s = drain(false); !s) return fail(s);
      continue;
    }
    pf.readable = true;
    auto shared = std::make_shared<FrameRecord>(std::move(*rec));
    const FrameRecord& r = *shared;
    for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
      const int c = index_of(id);
      const Frame& f = r.raw[id];
      if (f.image.empty()) continue;
      pf.t_ns[c] = clk.map(c, f.t_ns);
      pf.sequence[c] = f.sequence;
      const Image* images[3] = {&f.image, &r.augmented[c], &r.mask[c]};
      CameraJob job;
      job.rec = shared;
      job.camera = c;
      bool any = false;
      for (int k = 0; k < 3; ++k) {
        if (images[k]->empty() || (k == 2 && !options.masks))
          continue;  // masks read for the ground truth only
        StreamOut& so = streams[k][c];
        if (!so.created) {
          fs::create_directories(so.dir / "data", ec);
          if (ec)
            return fail(
                make_error((so.dir / "data").string(), ": cannot create the folder (", ec.message(), ")"));
          so.created = true;
          so.format = images[k]->format();
          so.clock = clk.clock;
          so.width = images[k]->width();
          so.height = images[k]->height();
        }
        if (!so.seen.insert(pf.t_ns[c]).second) {
          report.problems.push_back("frame " + std::to_string(i) + ": " + so.dir.filename().string() +
                                    ": timestamp " + std::to_string(pf.t_ns[c]) +
                                    " repeats; the later image is not written");
          continue;
        }
        job.files[k] = so.dir / "data" / (std::to_string(pf.t_ns[c]) + ".png");
        pf.write[k][c] = any = true;
      }
      if (!any) continue;
      if (pool) {
        ++pf.jobs;
        pool->push(i, std::move(job));
      } else if (auto s = run_camera_job(job, *inline_enc); !s) {
        return fail(s);
      }
      if (c == 0 && r.T_body_receiver && r.receiver_present.value_or(true))
        receiver_states.emplace_back(pf.t_ns[0], *r.T_body_receiver);
      // A frame augmented without the receiver (no nav pose yet) has no pose to export.
      if (const auto& T = r.T_cam_receiver[c]; T && r.receiver_present.value_or(true)) {
        nav::CameraPoseRow p;
        p.sequence = f.sequence;
        p.camera = c;
        p.t_ns = pf.t_ns[c];
        p.t_nav_ns = pf.t_ns[c];
        p.x_m = T->translation_m.x();
        p.y_m = T->translation_m.y();
        p.z_m = T->translation_m.z();
        const Eigen::Quaterniond q = T->rotation.normalized();
        p.qw = q.w();
        p.qx = q.x();
        p.qy = q.y();
        p.qz = q.z();
        p.sigma_pos_m = r.sigma_pos_m;
        p.sigma_att_deg = r.sigma_att_deg;
        if (r.boom) {
          p.boom_elevation_deg = rad_to_deg(r.boom->elevation_rad);
          p.boom_azimuth_deg = rad_to_deg(r.boom->azimuth_rad);
          p.boom_extension_m = r.boom->extension_m;
        }
        poses.push_back(p);
      }
    }
    if (options.ground_truth && !r.raw.left.image.empty() && !r.raw.right.image.empty()) {
      if (r.receiver_depth[0].empty() || r.receiver_depth[1].empty())
        return fail(no_depth_error(reader, i, r.raw.pair_sequence));
      for (int c = 0; c < 2; ++c) {
        const CameraModel& m = rig.cameras[static_cast<std::size_t>(c)].model;
        if (r.receiver_depth[c].width != m.width_px || r.receiver_depth[c].height != m.height_px)
          return fail(
              make_error(reader.path(), ": frame ", i, ": the ", c ? "right" : "left", " receiver depth is ",
                         r.receiver_depth[c].width, "x", r.receiver_depth[c].height, ", the rig's ",
                         rig.cameras[static_cast<std::size_t>(c)].name, " camera ", m.width_px, "x",
                         m.height_px, ": the ground truth needs the rig the recording was made with"));
      }
      CameraJob job;
      job.rec = shared;
      job.camera = kGroundTruthJob;
      job.rig = &rig;
      bool any = false;
      for (int k = 0; k < kGtStreams; ++k) {
        // The stereo classes come from both masks; a frame recorded without them has none.
        if (k == kGtStereoClass && (r.mask[0].empty() || r.mask[1].empty())) {
          if (!no_class_noted)
            report.notes.push_back("frame " + std::to_string(i) + " (and maybe others) has no masks: " +
                                   kGtFolder[k] + " is not written for such frames");
          no_class_noted = true;
          continue;
        }
        GtStreamOut& so = gt[k];
        const TimestampNs t = pf.t_ns[kGtCamera[k]];
        if (!so.created) {
          fs::create_directories(so.dir / "data", ec);
          if (ec)
            return fail(
                make_error((so.dir / "data").string(), ": cannot create the folder (", ec.message(), ")"));
          so.created = true;
        }
        if (!so.seen.insert(t).second) continue;  // a repeated time: reported with the images
        job.gt_files[k] = so.dir / "data" / (std::to_string(t) + kGtExt[k]);
        pf.write_gt[k] = any = true;
      }
      if (any) {
        if (pool) {
          ++pf.jobs;
          pool->push(i, std::move(job));
        } else if (auto s = run_camera_job(job, *inline_enc); !s) {
          return fail(s);
        }
      }
    }
    if (!r.raw.left.image.empty() && !r.raw.right.image.empty())
      max_skew_ns = std::max(max_skew_ns, std::abs(r.raw.right.t_ns - r.raw.left.t_ns));
    if (!r.augmented[0].empty() || !r.augmented[1].empty()) ++report.augmented_written;
    if (options.masks && (!r.mask[0].empty() || !r.mask[1].empty())) ++report.masks_written;
    if (r.stats) {
      OcclusionStats s = *r.stats;
      // The statistics' time is the pair's, on the left camera's clock.
      s.t_ns = clk.map(0, s.t_ns == 0 ? r.raw.t_key_ns : s.t_ns);
      stats.push_back(s);
    }
    shared.reset();
    pending.push_back(pf);
    if (auto s = drain(false); !s) return fail(s);
  }
  if (auto s = drain(true); !s) return fail(s);
  if (pool) pool->stop();

  // data.csv and sensor.yaml of every stream written.
  for (int k = 0; k < 3; ++k) {
    for (int c = 0; c < 2; ++c) {
      StreamOut& w = streams[k][c];
      if (!w.created) continue;
      if (auto s = write_text(w.dir / "data.csv", std::string(kCameraCsvHeader) + "\n" + w.csv); !s)
        return make_error(where, s.error().message);
      const RigCamera& cam = rig.cameras[static_cast<std::size_t>(c)];
      if (w.width != cam.model.width_px || w.height != cam.model.height_px) {
        report.notes.push_back(w.dir.filename().string() + ": images are " + std::to_string(w.width) + "x" +
                               std::to_string(w.height) + ", the rig's " + cam.name + " camera is " +
                               std::to_string(cam.model.width_px) + "x" +
                               std::to_string(cam.model.height_px));
      }
      const char* stream = k == 0 ? "raw" : k == 1 ? "augmented" : "mask";
      if (auto s = write_text(w.dir / "sensor.yaml", euroc_camera_yaml(cam, c == 0 ? "left" : "right", stream,
                                                                       report.rate_hz, w.format, w.clock));
          !s)
        return make_error(where, s.error().message);
    }
  }
  for (int k = 0; k < kGtStreams; ++k) {
    const GtStreamOut& g = gt[k];
    if (!g.created) continue;
    if (auto s = write_text(g.dir / "data.csv", std::string(kCameraCsvHeader) + "\n" + g.csv); !s)
      return make_error(where, s.error().message);
    if (auto s = write_text(g.dir / "sensor.yaml",
                            ground_truth_yaml(k, rig.cameras[static_cast<std::size_t>(kGtCamera[k])],
                                              report.rate_hz, clk.clock));
        !s)
      return make_error(where, s.error().message);
  }
  if (max_skew_ns > 0) {
    report.notes.push_back("left and right timestamps differ (up to " + std::to_string(max_skew_ns) +
                           " ns): readers that pair cam0 and cam1 by identical timestamps need a tolerance");
  }
  if (options.augmented && streams[1][0].written + streams[1][1].written == 0)
    report.notes.push_back(
        "no augmented images in the recording: cam0_augmented, cam1_augmented not written");
  if (options.masks && streams[2][0].written + streams[2][1].written == 0)
    report.notes.push_back("no masks in the recording: cam0_mask, cam1_mask not written");

  // imu0 from the recording's IMU nav inputs.
  if (inputs) {
    std::string stream = options.imu_stream;
    bool several = false;
    if (stream.empty()) {
      if (by_stream.count("imu"))
        stream = "imu";
      else if (by_stream.count("tanker.imu"))
        stream = "tanker.imu";
      else {
        std::vector<std::string> imus;
        for (const auto& [name, rows] : by_stream)
          if (name.size() >= 3 && name.compare(name.size() - 3, 3, "imu") == 0) imus.push_back(name);
        if (imus.size() == 1) stream = imus[0];
        several = imus.size() > 1;
        if (several)
          report.notes.push_back(
              "several IMU streams and none is 'imu' or 'tanker.imu': imu0 not written (choose one)");
      }
    } else if (!by_stream.count(stream)) {
      report.problems.push_back("nav input stream '" + stream +
                                "' is not in the recording; imu0 not exported");
      stream.clear();
    }
    if (stream.empty() && options.imu_stream.empty() && !several) {
      std::string names;
      for (const auto& [name, rows] : by_stream) names += (names.empty() ? "" : ", ") + name;
      report.notes.push_back(by_stream.empty()
                                 ? "no nav inputs in the recording: imu0 not written"
                                 : "no IMU stream among the nav inputs (" + names + "): imu0 not written");
    }
    if (!stream.empty()) {
      auto data = imu_stream_data(by_stream[stream], reader.path() + " nav_input '" + stream + "'");
      if (!data) {
        report.problems.push_back(strip_function(data.error().message) + "; imu0 not exported");
      } else {
        const fs::path dir = mav0 / "imu0";
        fs::create_directories(dir, ec);
        std::string csv = std::string(kImuCsvHeader) + "\n";
        std::vector<TimestampNs> t;
        for (const nav::ImuSample& s : data->samples) {
          if (!(s.dt_s > 0)) continue;
          // The increments' mean rates, stamped at the middle of their interval (t_ns - dt/2).
          const TimestampNs tm = s.t_ns - s_to_ns(0.5 * s.dt_s);
          const Eigen::Vector3d w = s.dtheta_rad / s.dt_s, a = s.dv_mps / s.dt_s;
          csv += std::to_string(tm) + "," + num(w.x()) + "," + num(w.y()) + "," + num(w.z()) + "," +
                 num(a.x()) + "," + num(a.y()) + "," + num(a.z()) + "\n";
          t.push_back(tm);
        }
        report.imu_stream = stream;
        report.imu_samples = t.size();
        if (data->repeats > 0)
          report.notes.push_back("imu0: " + std::to_string(data->repeats) +
                                 " out-of-order or repeated samples dropped");
        if (data->undecodable > 0)
          report.problems.push_back(
              "imu0: " + std::to_string(data->undecodable) + " IMU datagram(s) of '" + stream +
              "' do not decode, their samples are missing (first: " + data->first_error + ")");
        if (data->clock != clk.clock)
          report.notes.push_back("imu0 is on the IMU's own clock (" + std::string(to_string(data->clock)) +
                                 "), not the frames' (" + std::string(to_string(clk.clock)) + ")");
        if (auto s = write_text(dir / "data.csv", csv); !s) return make_error(where, s.error().message);
        std::ostringstream y;
        y << "# augrig export: nav input stream '" << stream
          << "' as rates. Each row is the mean rate over one\n"
          << "# recorded increment, stamped at the middle of its interval. The IMU axes are the body axes\n"
          << "# (tanker body FRD), so T_BS is the identity. Noise densities are not known to augrig.\n"
          << "sensor_type: imu\n"
          << "comment: \"augrig " << stream << "\"\n"
          << "T_BS:\n  cols: 4\n  rows: 4\n  data: " << matrix_row_major(Eigen::Matrix4d::Identity()) << "\n"
          << "rate_hz: " << num(median_rate_hz(t)) << "\n"
          << "augrig:\n  stream: " << stream << "\n  clock: " << to_string(data->clock) << "\n";
        if (auto s = write_text(dir / "sensor.yaml", y.str()); !s)
          return make_error(where, s.error().message);
      }
    }

    // Per aircraft: the log folder `augrig nav` fuses (docs/NAV_FORMATS.md).
    for (const std::string who : {"tanker", "receiver"}) {
      const auto gps = by_stream.find(who + ".gps"), imu = by_stream.find(who + ".imu");
      if (gps == by_stream.end() && imu == by_stream.end()) continue;
      if (gps == by_stream.end() || imu == by_stream.end()) {
        report.notes.push_back("nav/" + who + " not written: the recording has '" +
                               (gps == by_stream.end() ? imu->first : gps->first) + "' but not '" +
                               (gps == by_stream.end() ? who + ".gps" : who + ".imu") + "'");
        continue;
      }
      const fs::path dir = out / "nav" / who;
      fs::create_directories(dir, ec);
      if (ec) return make_error(where, dir.string(), ": cannot create the folder (", ec.message(), ")");
      std::string nmea;
      std::size_t other = 0;
      for (const NavInputRecord* r : gps->second) {
        if (r->binary || !is_nmea_line(r->data)) {
          ++other;
          continue;
        }
        if (r->arrival_ns != 0) nmea += std::to_string(r->arrival_ns) + " ";
        nmea += r->data + "\r\n";
      }
      if (other > 0)
        report.notes.push_back("nav/" + who + "/gps.nmea: " + std::to_string(other) + " input(s) of '" +
                               gps->first + "' are not NMEA sentences (gpsd reports?) and are not in it");
      if (auto s = write_text(dir / "gps.nmea", nmea); !s) return make_error(where, s.error().message);
      auto data = imu_stream_data(imu->second, reader.path() + " nav_input '" + imu->first + "'");
      if (!data) {
        report.problems.push_back(strip_function(data.error().message) + "; nav/" + who +
                                  "/imu.csv not written");
        continue;
      }
      nav::CsvWriteOptions o;
      o.clock = data->clock;
      o.metadata["content"] = "nav input stream '" + imu->first + "' as recorded (augrig export)";
      if (auto s = nav::write_imu_csv((dir / "imu.csv").string(), data->samples, o); !s)
        return make_error(where, strip_function(s.error().message));
      std::string yaml;
      if (auto it = options.aircraft_yaml.find(who); it != options.aircraft_yaml.end())
        yaml = it->second;
      else
        yaml = reader.meta("aircraft_yaml." + who);
      if (!yaml.empty()) {
        if (auto s = write_text(dir / "aircraft.yaml", yaml); !s) return make_error(where, s.error().message);
      } else {
        report.notes.push_back("nav/" + who + "/aircraft.yaml not written: the recording does not hold the " +
                               who + "'s settings (give them: --aircraft " + who +
                               "=FILE); augrig nav uses defaults (no lever arm)");
      }
      report.nav_logs.push_back(who);
    }
  }

  if (!index.rows.empty()) {
    if (auto s = nav::write_frame_index_csv((out / "frames.csv").string(), index); !s)
      return make_error(where, strip_function(s.error().message));
    report.frame_index_rows = index.rows.size();
  }
  if (auto s = write_text(out / "rig.yaml", rig_to_yaml(rig)); !s)
    return make_error(where, s.error().message);

  if (!poses.empty()) {
    nav::CsvWriteOptions o;
    o.clock = clk.clock;
    o.metadata["content"] = "T_cam_receiver as recorded (augrig export)";
    o.metadata["t_nav_ns"] = "not recorded: equals t_ns";
    if (auto s = nav::write_camera_pose_csv((out / "poses.csv").string(), poses, o); !s)
      return make_error(where, strip_function(s.error().message));
    report.pose_rows = poses.size();
  } else {
    report.notes.push_back("no poses in the recording: poses.csv not written");
  }

  if (!receiver_states.empty()) {
    if (auto s = write_receiver_states(out / "mav0" / "state_groundtruth_estimate0", receiver_states); !s)
      return make_error(where, s.error().message);
  } else {
    report.notes.push_back(
        "no receiver poses in the recording: mav0/state_groundtruth_estimate0 not written");
  }

  if (!stats.empty()) {
    std::ofstream csv(out / "stats.csv", std::ios::binary);
    write_stats_csv_header(csv);
    for (const OcclusionStats& s : stats) write_stats_csv_row(csv, s);
    csv.close();
    if (!csv) return make_error(where, (out / "stats.csv").string(), ": cannot write the file");
    report.stats_rows = stats.size();
    // The flight's phases recorded beside the statistics ("phase: NAME" events, on their clock):
    // OUT/phases.csv and the plot's markers.
    std::vector<PhaseEvent> phases;
    if (auto ev = reader.events()) phases = phase_events(*ev);
    for (PhaseEvent& ph : phases) ph.t_ns = clk.map(0, ph.t_ns);
    if (!phases.empty()) {
      std::ofstream pcsv(out / "phases.csv", std::ios::binary);
      pcsv << "#t_ns,t_s,phase\n";
      for (const PhaseEvent& ph : phases) {
        char t_s[32];
        std::snprintf(t_s, sizeof t_s, "%.6f", ns_to_s(ph.t_ns - stats.front().t_ns));
        pcsv << ph.t_ns << ',' << t_s << ',' << ph.name << '\n';
      }
      pcsv.close();
      if (!pcsv) return make_error(where, (out / "phases.csv").string(), ": cannot write the file");
      report.phases = phases.size();
    }
    if (options.plot) {
      StatsPlotOptions po;
      po.title = "Occlusion statistics: " + fs::path(reader.path()).parent_path().filename().string();
      po.phases = phase_markers(phases, stats.front().t_ns, stats.back().t_ns);
      if (auto s = plot_occlusion_stats(stats, (out / "stats.png").string(), po); !s)
        report.problems.push_back(strip_function(s.error().message));
      else
        report.plotted = true;
    }
  } else {
    report.notes.push_back("no occlusion statistics in the recording: stats.csv and stats.png not written");
  }
  progress(true);
  return {};
}

}  // namespace

Status export_euroc(const RecordingReader& reader, const std::string& out_dir,
                    const EurocExportOptions& options, EurocExportReport& report) {
  const std::string where = "recorder::export_euroc(): ";
  report = {};
  Rig rig;
  if (options.rig) {
    rig = *options.rig;
  } else {
    const std::string yaml = reader.meta("rig_yaml");
    if (yaml.empty())
      return make_error(where, reader.path(),
                        ": the recording stores no rig (meta rig_yaml is empty); give one");
    auto r = parse_rig(yaml, reader.path() + " (meta rig_yaml)");
    if (!r) return make_error(where, strip_function(r.error().message));
    rig = std::move(*r);
  }
  if (rig.cameras.size() < 2)
    return make_error(where, rig.source, ": the rig needs 2 cameras, has ", rig.cameras.size());
  // Every frame needs its recorded depth: said before anything is written.
  if (options.ground_truth) {
    std::size_t missing = 0, first = 0;
    for (std::size_t i = 0; i < reader.frame_count(); ++i)
      if (!reader.has_depth(i) && missing++ == 0) first = i;
    if (missing) {
      const auto info = reader.read_frame_info(first);
      return make_error(where, no_depth_error(reader, first, info ? info->raw.pair_sequence : first,
                                              " (" + std::to_string(missing) + " of " +
                                                  std::to_string(reader.frame_count()) + " frames hold none)")
                                   .message);
    }
  }

  const fs::path out(out_dir), mav0 = out / "mav0", marker = out / "INCOMPLETE";
  std::error_code ec;
  if (fs::exists(mav0, ec))
    return make_error(where, mav0.string(), ": exists already; export into a new folder (exports never mix)");
  fs::create_directories(out, ec);
  if (ec) return make_error(where, out.string(), ": cannot create the folder (", ec.message(), ")");
  // OUT/INCOMPLETE before OUT/mav0 and anything in it: an export killed at any moment is marked.
  write_marker(marker, reader.path(), out_dir, {});
  if (!fs::exists(marker, ec)) return make_error(where, marker.string(), ": cannot write the file");
  fs::create_directories(mav0, ec);
  if (ec) return make_error(where, mav0.string(), ": cannot create the folder (", ec.message(), ")");

  Status s = export_body(reader, out, options, rig, report);
  if (!s) {
    write_marker(marker, reader.path(), out_dir, {s.error().message});
    return s;
  }
  if (!report.problems.empty()) {
    write_marker(marker, reader.path(), out_dir, report.problems);
    return {};
  }
  fs::remove(marker, ec);
  if (ec) return make_error(where, marker.string(), ": cannot remove it (", ec.message(), ")");
  return {};
}

// ---- Reading ------------------------------------------------------------------------------------------

Expected<std::vector<EurocCsvRow>> read_euroc_camera_csv(const std::string& path) {
  const std::string where = "recorder::read_euroc_camera_csv(): ";
  if (auto d = check_not_directory(where, path); !d) return d.error();
  std::ifstream in(path, std::ios::binary);
  if (!in) return make_error(where, path, ": cannot open the file");
  std::vector<EurocCsvRow> rows;
  std::string line;
  for (std::size_t no = 1; std::getline(in, line); ++no) {
    const std::string_view l = trim_csv_cell(line);
    if (l.empty() || l.front() == '#') continue;
    const auto f = split_csv_line_trimmed(l);
    if (f.size() != 2)
      return make_error(where, path, ":", no, ": expected 2 fields (timestamp [ns],filename), got ",
                        f.size());
    EurocCsvRow r;
    if (!parse_i64(f[0], r.t_ns))
      return make_error(where, path, ":", no, ": timestamp: expected whole nanoseconds, got '",
                        std::string(f[0]), "'");
    if (!nav::is_supported_timestamp(r.t_ns))
      return make_error(where, path, ":", no, ": timestamp: expected a time in ", nav::kTimestampRangeText,
                        ", got '", std::string(f[0]), "'");
    if (f[1].empty()) return make_error(where, path, ":", no, ": filename is empty");
    r.file = std::string(f[1]);
    rows.push_back(std::move(r));
  }
  return rows;
}

Expected<std::vector<EurocImuRow>> read_euroc_imu_csv(const std::string& path) {
  const std::string where = "recorder::read_euroc_imu_csv(): ";
  if (auto d = check_not_directory(where, path); !d) return d.error();
  std::ifstream in(path, std::ios::binary);
  if (!in) return make_error(where, path, ": cannot open the file");
  std::vector<EurocImuRow> rows;
  std::string line;
  for (std::size_t no = 1; std::getline(in, line); ++no) {
    const std::string_view l = trim_csv_cell(line);
    if (l.empty() || l.front() == '#') continue;
    const auto f = split_csv_line_trimmed(l);
    if (f.size() != 7)
      return make_error(where, path, ":", no, ": expected 7 fields (timestamp, w_RS_S xyz, a_RS_S xyz), got ",
                        f.size());
    EurocImuRow r;
    // Bounded (nav/gps_time.hpp) so that the intervals between rows cannot overflow int64.
    if (!parse_i64(f[0], r.t_ns))
      return make_error(where, path, ":", no, ": timestamp: expected whole nanoseconds, got '",
                        std::string(f[0]), "'");
    if (!nav::is_supported_timestamp(r.t_ns))
      return make_error(where, path, ":", no, ": timestamp: expected a time in ", nav::kTimestampRangeText,
                        ", got '", std::string(f[0]), "'");
    for (int k = 0; k < 6; ++k) {
      double v = 0;
      if (!parse_f64(f[static_cast<std::size_t>(k + 1)], v))
        return make_error(where, path, ":", no, ": field ", k + 2, ": expected a finite number, got '",
                          std::string(f[static_cast<std::size_t>(k + 1)]), "'");
      (k < 3 ? r.w_rad_s : r.a_mps2)[k % 3] = v;
    }
    if (!rows.empty() && r.t_ns <= rows.back().t_ns)
      return make_error(where, path, ":", no, ": timestamp ", r.t_ns, " is not after the previous row's ",
                        rows.back().t_ns);
    rows.push_back(r);
  }
  return rows;
}

std::vector<nav::ImuSample> imu_increments(const std::vector<EurocImuRow>& rows) {
  std::vector<nav::ImuSample> out;
  for (std::size_t k = 1; k < rows.size(); ++k) {
    nav::ImuSample s;
    s.t_ns = rows[k].t_ns;
    s.dt_s = ns_to_s(rows[k].t_ns - rows[k - 1].t_ns);
    s.dtheta_rad = 0.5 * (rows[k - 1].w_rad_s + rows[k].w_rad_s) * s.dt_s;
    s.dv_mps = 0.5 * (rows[k - 1].a_mps2 + rows[k].a_mps2) * s.dt_s;
    out.push_back(s);
  }
  return out;
}

Expected<std::unique_ptr<EurocSource>> EurocSource::open(const std::string& uri_or_dir,
                                                         const EurocOptions& options) {
  const std::string where = "recorder::EurocSource::open(): ";
  std::string dir = uri_or_dir;
  if (dir.rfind(kEurocScheme, 0) == 0) dir = dir.substr(kEurocScheme.size());
  if (dir.empty()) return make_error(where, "'", uri_or_dir, "': expected euroc://DIR or a dataset folder");
  std::error_code ec;
  fs::path mav0;
  if (fs::is_directory(fs::path(dir) / "mav0", ec))
    mav0 = fs::path(dir) / "mav0";
  else if (fs::is_regular_file(fs::path(dir) / options.left_stream / "data.csv", ec))
    mav0 = dir;
  else if (!fs::exists(dir, ec))
    return make_error(where, dir, ": no such folder");
  else
    return make_error(where, dir, ": not a EuRoC/ASL dataset (no mav0/", options.left_stream, "/data.csv)");

  std::unique_ptr<EurocSource> s(new EurocSource());
  s->uri_ = std::string(kEurocScheme) + dir;
  s->mav0_ = mav0.string();
  s->options_ = options;
  std::vector<EurocCsvRow> rows[2];
  const std::string names[2] = {options.left_stream, options.right_stream};
  for (int c = 0; c < 2; ++c) {
    auto r = read_euroc_camera_csv((mav0 / names[c] / "data.csv").string());
    if (!r) return make_error(where, strip_function(r.error().message));
    rows[c] = std::move(*r);
    std::stable_sort(rows[c].begin(), rows[c].end(),
                     [](const auto& a, const auto& b) { return a.t_ns < b.t_ns; });
    std::optional<PixelFormat> f;
    std::optional<ClockDomain> clock;
    if (auto k = read_augrig_keys(mav0 / names[c] / "sensor.yaml", f, clock); !k)
      return make_error(where, k.error().message);
    s->gray_[c] = options.gray_format.value_or(f.value_or(PixelFormat::kMono8));
    s->clock_[c] = options.clock.value_or(clock.value_or(ClockDomain::kUnknown));
  }
  // Pairs: a merge of both time-sorted lists.
  std::size_t i = 0, j = 0;
  const std::int64_t tol = std::max<std::int64_t>(0, options.pair_tolerance_ns);
  while (i < rows[0].size() && j < rows[1].size()) {
    const std::int64_t d = rows[1][j].t_ns - rows[0][i].t_ns;
    if (d >= -tol && d <= tol) {
      s->pairs_.push_back({rows[0][i++], rows[1][j++]});
    } else if (d > 0) {
      ++i, ++s->unpaired_;
    } else {
      ++j, ++s->unpaired_;
    }
  }
  s->unpaired_ += (rows[0].size() - i) + (rows[1].size() - j);
  // The start: the pairs before it are outside the range played, not lost.
  std::size_t start = options.start_pair;
  if (options.start_offset_ns && !s->pairs_.empty()) {
    const std::int64_t t0 = s->pairs_.front().left.t_ns;
    start = 0;
    while (start < s->pairs_.size() && s->pairs_[start].left.t_ns - t0 < *options.start_offset_ns) ++start;
  }
  if (start > 0 && start >= s->pairs_.size())
    return make_error(where, dir, ": the start (pair ", start, ") is past the last pair (", s->pairs_.size(),
                      " pairs)");
  if (!s->pairs_.empty()) s->first_t_ns_ = s->pairs_.front().left.t_ns;
  s->start_ = start;
  s->pairs_.erase(s->pairs_.begin(), s->pairs_.begin() + static_cast<std::ptrdiff_t>(start));

  const fs::path imu = mav0 / "imu0" / "data.csv";
  if (fs::exists(imu, ec)) {
    auto r = read_euroc_imu_csv(imu.string());
    if (!r) return make_error(where, strip_function(r.error().message));
    s->imu_ = std::move(*r);
  }
  return s;
}

Status EurocSource::set_end_pair(std::size_t end) {
  if (end <= start_)
    return make_error("recorder::EurocSource::set_end_pair(): ", mav0_, ": the end (pair ", end,
                      ") is not after the start (pair ", start_, ")");
  if (end - start_ < pairs_.size()) pairs_.resize(end - start_);
  return {};
}

Expected<ReadStatus> EurocSource::read(Frame& out, std::chrono::nanoseconds) {
  if (right_pending_) {
    right_pending_ = false;
    out = std::move(right_);
    right_ = Frame{};
    return ReadStatus::kFrame;
  }
  if (next_ >= pairs_.size()) return ReadStatus::kEndOfStream;
  const std::size_t k = next_++;
  const Pair& p = pairs_[k];
  Frame f[2];
  const EurocCsvRow* rows[2] = {&p.left, &p.right};
  const std::string names[2] = {options_.left_stream, options_.right_stream};
  for (int c = 0; c < 2; ++c) {
    auto im = read_png(fs::path(mav0_) / names[c] / "data" / rows[c]->file, gray_[c]);
    if (!im) {
      ++unreadable_;
      return make_error("recorder::EurocSource::read(): ", im.error().message, "; pair ", k, " (t_ns ",
                        rows[c]->t_ns, ") skipped, the next read() goes on");
    }
    f[c].image = std::move(*im);
    f[c].t_ns = rows[c]->t_ns;
    f[c].clock = clock_[c];
    f[c].sequence = k;
    f[c].camera = c == 0 ? CameraId::kLeft : CameraId::kRight;
  }
  out = std::move(f[0]);
  right_ = std::move(f[1]);
  right_pending_ = true;
  return ReadStatus::kFrame;
}

}  // namespace augrig::recorder
