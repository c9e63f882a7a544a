// EurocSource and the readers of a EuRoC/ASL dataset's CSV files (euroc_source.hpp).
#include "recorder/euroc_source.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string_view>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <yaml-cpp/yaml.h>

#include "core/csv.hpp"
#include "core/file_check.hpp"
#include "nav/gps_time.hpp"
#include "recorder/record.hpp"

namespace augrig::recorder {

namespace fs = std::filesystem;

namespace {

// "module::function(): rest" -> "rest", so that errors read as the source's own (as
// replay_source.cpp and the export's euroc_detail do).
std::string strip_function(const std::string& m) {
  const auto p = m.find("(): ");
  if (p != std::string::npos && p < 64 && m.find(' ') > p) return m.substr(p + 4);
  return m;
}

constexpr std::string_view kEurocScheme = "euroc://";

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

// A data line's timestamp cell: whole nanoseconds, within nav/gps_time.hpp's range (so that the
// intervals between rows cannot overflow int64).
Status parse_timestamp(std::string_view cell, const std::string& at, TimestampNs& t_ns) {
  if (!parse_csv_int64(cell, t_ns))
    return make_error(at, ": timestamp: expected whole nanoseconds, got '", std::string(cell), "'");
  if (!nav::is_supported_timestamp(t_ns))
    return make_error(at, ": timestamp: expected a time in ", nav::kTimestampRangeText, ", got '",
                      std::string(cell), "'");
  return {};
}

}  // namespace

Expected<std::vector<EurocCsvRow>> read_euroc_camera_csv(const std::string& path) {
  const std::string where = "recorder::read_euroc_camera_csv(): ";
  std::vector<EurocCsvRow> rows;
  const Status s = for_each_csv_row(path, where, [&](std::size_t no, const auto& f) -> Status {
    const std::string at = where + path + ":" + std::to_string(no);
    if (f.size() != 2) return make_error(at, ": expected 2 fields (timestamp [ns],filename), got ", f.size());
    EurocCsvRow r;
    if (Status t = parse_timestamp(f[0], at, r.t_ns); !t) return t;
    if (f[1].empty()) return make_error(at, ": filename is empty");
    r.file = std::string(f[1]);
    rows.push_back(std::move(r));
    return {};
  });
  if (!s) return s.error();
  return rows;
}

Expected<std::vector<EurocImuRow>> read_euroc_imu_csv(const std::string& path) {
  const std::string where = "recorder::read_euroc_imu_csv(): ";
  std::vector<EurocImuRow> rows;
  const Status s = for_each_csv_row(path, where, [&](std::size_t no, const auto& f) -> Status {
    const std::string at = where + path + ":" + std::to_string(no);
    if (f.size() != 7)
      return make_error(at, ": expected 7 fields (timestamp, w_RS_S xyz, a_RS_S xyz), got ", f.size());
    EurocImuRow r;
    if (Status t = parse_timestamp(f[0], at, r.t_ns); !t) return t;
    for (int k = 0; k < 6; ++k) {
      double v = 0;
      const std::string_view cell = f[static_cast<std::size_t>(k + 1)];
      if (!parse_csv_double(cell, v))
        return make_error(at, ": field ", k + 2, ": expected a finite number, got '", std::string(cell), "'");
      (k < 3 ? r.w_rad_s : r.a_mps2)[k % 3] = v;
    }
    if (!rows.empty() && r.t_ns <= rows.back().t_ns)
      return make_error(at, ": timestamp ", r.t_ns, " is not after the previous row's ", rows.back().t_ns);
    rows.push_back(r);
    return {};
  });
  if (!s) return s.error();
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
