#include "recorder/euroc.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <yaml-cpp/yaml.h>

#include "core/file_check.hpp"
#include "nav/gps_time.hpp"
#include "nav/logs.hpp"
#include "recorder/plot.hpp"
#include "recorder/record.hpp"
#include "render/image_file.hpp"

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

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> f;
  std::size_t pos = 0;
  for (;;) {
    const auto c = line.find(',', pos);
    f.push_back(trim(line.substr(pos, c == std::string_view::npos ? std::string_view::npos : c - pos)));
    if (c == std::string_view::npos) break;
    pos = c + 1;
  }
  return f;
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

std::string matrix_row_major(const Eigen::Matrix4d& T) {
  std::string s = "[";
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) s += (r || c ? ", " : "") + num(T(r, c));
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

// One output image stream: mav0/<name>/data/<t_ns>.png and data.csv.
struct StreamWriter {
  fs::path dir;
  std::ofstream csv;
  std::set<TimestampNs> seen;
  std::size_t written = 0;
  PixelFormat format = PixelFormat::kMono8;
  ClockDomain clock = ClockDomain::kUnknown;
  int width = 0, height = 0;

  // false and `problem` set when the timestamp repeats (the image is not written).
  Status add(const Frame& f, const Image& image, int compression, std::string* problem) {
    if (!csv.is_open()) {
      std::error_code ec;
      fs::create_directories(dir / "data", ec);
      if (ec) return make_error((dir / "data").string(), ": cannot create the folder (", ec.message(), ")");
      csv.open(dir / "data.csv", std::ios::binary);
      if (!csv) return make_error((dir / "data.csv").string(), ": cannot write the file");
      csv << kCameraCsvHeader << "\n";
      format = image.format();
      clock = f.clock;
      width = image.width();
      height = image.height();
    }
    if (!seen.insert(f.t_ns).second) {
      *problem = dir.filename().string() + ": timestamp " + std::to_string(f.t_ns) +
                 " repeats; the later image is not written";
      return {};
    }
    const std::string name = std::to_string(f.t_ns) + ".png";
    if (auto s = write_png_file((dir / "data" / name).string(), image, compression); !s) return s;
    csv << f.t_ns << "," << name << "\n";
    if (!csv) return make_error((dir / "data.csv").string(), ": write failed");
    ++written;
    return {};
  }
};

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

  const fs::path out(out_dir), mav0 = out / "mav0";
  std::error_code ec;
  if (fs::exists(mav0, ec))
    return make_error(where, mav0.string(), ": exists already; export into a new folder (exports never mix)");
  fs::create_directories(mav0, ec);
  if (ec) return make_error(where, mav0.string(), ": cannot create the folder (", ec.message(), ")");

  const std::size_t n = reader.frame_count();
  report.frames = n;
  // The rate from every frame's time, before any image is decoded.
  {
    std::vector<TimestampNs> t;
    for (std::size_t i = 0; i < n; ++i)
      if (auto info = reader.read_frame_info(i)) t.push_back(info->raw.t_key_ns);
    report.rate_hz = median_rate_hz(std::move(t));
  }

  const char* kStreams[3] = {"", "_augmented", "_mask"};
  StreamWriter streams[3][2];
  for (int k = 0; k < 3; ++k)
    for (int c = 0; c < 2; ++c) streams[k][c].dir = mav0 / ("cam" + std::to_string(c) + kStreams[k]);
  unsigned parts = kPartRaw;
  if (options.augmented) parts |= kPartAugmented;
  if (options.masks) parts |= kPartMasks;

  std::vector<nav::CameraPoseRow> poses;
  std::vector<OcclusionStats> stats;
  ClockDomain pose_clock = ClockDomain::kUnknown;
  std::int64_t max_skew_ns = 0;
  for (std::size_t i = 0; i < n; ++i) {
    auto rec = reader.read_frame(i, parts);
    if (!rec) {
      report.problems.push_back(strip_function(rec.error().message) + "; frame not exported");
      continue;
    }
    for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
      const int c = index_of(id);
      const Frame& f = rec->raw[id];
      if (f.image.empty()) continue;
      const Image* images[3] = {&f.image, &rec->augmented[c], &rec->mask[c]};
      for (int k = 0; k < 3; ++k) {
        if (images[k]->empty()) continue;
        std::string problem;
        if (auto s = streams[k][c].add(f, *images[k], options.png_compression, &problem); !s)
          return make_error(where, s.error().message);
        if (!problem.empty()) report.problems.push_back("frame " + std::to_string(i) + ": " + problem);
      }
      if (const auto& T = rec->T_cam_receiver[c]) {
        nav::CameraPoseRow p;
        p.sequence = f.sequence;
        p.camera = c;
        p.t_ns = f.t_ns;
        p.t_nav_ns = f.t_ns;
        p.x_m = T->translation_m.x();
        p.y_m = T->translation_m.y();
        p.z_m = T->translation_m.z();
        const Eigen::Quaterniond q = T->rotation.normalized();
        p.qw = q.w();
        p.qx = q.x();
        p.qy = q.y();
        p.qz = q.z();
        p.sigma_pos_m = rec->sigma_pos_m;
        p.sigma_att_deg = rec->sigma_att_deg;
        if (rec->boom) {
          p.boom_elevation_deg = rad_to_deg(rec->boom->elevation_rad);
          p.boom_azimuth_deg = rad_to_deg(rec->boom->azimuth_rad);
          p.boom_extension_m = rec->boom->extension_m;
        }
        poses.push_back(p);
        pose_clock = f.clock;
      }
    }
    if (!rec->raw.left.image.empty() && !rec->raw.right.image.empty())
      max_skew_ns = std::max(max_skew_ns, std::abs(rec->raw.right.t_ns - rec->raw.left.t_ns));
    if (!rec->augmented[0].empty() || !rec->augmented[1].empty()) ++report.augmented_written;
    if (!rec->mask[0].empty() || !rec->mask[1].empty()) ++report.masks_written;
    if (rec->stats) {
      OcclusionStats s = *rec->stats;
      if (s.t_ns == 0) s.t_ns = rec->raw.t_key_ns;
      stats.push_back(s);
    }
    ++report.frames_written;
  }

  // sensor.yaml of every stream written.
  for (int k = 0; k < 3; ++k) {
    for (int c = 0; c < 2; ++c) {
      StreamWriter& w = streams[k][c];
      if (!w.csv.is_open()) continue;
      w.csv.close();
      if (!w.csv) return make_error(where, (w.dir / "data.csv").string(), ": write failed");
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
  auto inputs = reader.nav_inputs();
  if (!inputs) {
    report.problems.push_back(strip_function(inputs.error().message) + "; imu0 not exported");
  } else {
    std::map<std::string, std::vector<const NavInputRecord*>> by_stream;
    for (const NavInputRecord& r : *inputs) by_stream[r.stream].push_back(&r);
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
              "several IMU streams and none is 'imu' or 'tanker.imu': imu0 not written "
              "(choose one)");
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
      std::string text = std::string(imu_input_header()) + "\n";
      for (const NavInputRecord* r : by_stream[stream]) text += r->data + "\n";
      std::istringstream in(text);
      auto log = nav::parse_imu_csv(in, reader.path() + " nav_input '" + stream + "'");
      if (!log) {
        report.problems.push_back(strip_function(log.error().message) + "; imu0 not exported");
      } else {
        const fs::path dir = mav0 / "imu0";
        fs::create_directories(dir, ec);
        std::ostringstream csv;
        csv << kImuCsvHeader << "\n";
        std::vector<TimestampNs> t;
        for (const nav::ImuSample& s : log->samples) {
          if (!(s.dt_s > 0)) continue;
          // The increments' mean rates, stamped at the middle of their interval (t_ns - dt/2).
          const TimestampNs tm = s.t_ns - s_to_ns(0.5 * s.dt_s);
          const Eigen::Vector3d w = s.dtheta_rad / s.dt_s, a = s.dv_mps / s.dt_s;
          csv << tm << "," << num(w.x()) << "," << num(w.y()) << "," << num(w.z()) << "," << num(a.x()) << ","
              << num(a.y()) << "," << num(a.z()) << "\n";
          t.push_back(tm);
        }
        report.imu_stream = stream;
        report.imu_samples = t.size();
        if (log->issues.out_of_order + log->issues.duplicates > 0) {
          report.notes.push_back(
              "imu0: " + std::to_string(log->issues.out_of_order + log->issues.duplicates) +
              " out-of-order or repeated samples dropped");
        }
        if (auto s = write_text(dir / "data.csv", csv.str()); !s) return make_error(where, s.error().message);
        std::ostringstream y;
        y << "# augrig export: nav input stream '" << stream
          << "' as rates. Each row is the mean rate over one\n"
          << "# recorded increment, stamped at the middle of its interval. The IMU axes are the body axes\n"
          << "# (tanker body FRD), so T_BS is the identity. Noise densities are not known to augrig.\n"
          << "sensor_type: imu\n"
          << "comment: \"augrig " << stream << "\"\n"
          << "T_BS:\n  cols: 4\n  rows: 4\n  data: " << matrix_row_major(Eigen::Matrix4d::Identity()) << "\n"
          << "rate_hz: " << num(median_rate_hz(t)) << "\n"
          << "augrig:\n  stream: " << stream << "\n  clock: " << to_string(log->clock) << "\n";
        if (auto s = write_text(dir / "sensor.yaml", y.str()); !s)
          return make_error(where, s.error().message);
      }
    }
  }

  if (!poses.empty()) {
    nav::CsvWriteOptions o;
    o.clock = pose_clock;
    o.metadata["content"] = "T_cam_receiver as recorded (augrig export)";
    o.metadata["t_nav_ns"] = "not recorded: equals t_ns";
    if (auto s = nav::write_camera_pose_csv((out / "poses.csv").string(), poses, o); !s)
      return make_error(where, strip_function(s.error().message));
    report.pose_rows = poses.size();
  } else {
    report.notes.push_back("no poses in the recording: poses.csv not written");
  }

  if (!stats.empty()) {
    std::ofstream csv(out / "stats.csv", std::ios::binary);
    write_stats_csv_header(csv);
    for (const OcclusionStats& s : stats) write_stats_csv_row(csv, s);
    csv.close();
    if (!csv) return make_error(where, (out / "stats.csv").string(), ": cannot write the file");
    report.stats_rows = stats.size();
    if (options.plot) {
      StatsPlotOptions po;
      po.title = "Occlusion statistics: " + fs::path(reader.path()).parent_path().filename().string();
      if (auto s = plot_occlusion_stats(stats, (out / "stats.png").string(), po); !s)
        report.problems.push_back(strip_function(s.error().message));
      else
        report.plotted = true;
    }
  } else {
    report.notes.push_back("no occlusion statistics in the recording: stats.csv and stats.png not written");
  }
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
    const std::string_view l = trim(line);
    if (l.empty() || l.front() == '#') continue;
    const auto f = split(l);
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
    const std::string_view l = trim(line);
    if (l.empty() || l.front() == '#') continue;
    const auto f = split(l);
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

  const fs::path imu = mav0 / "imu0" / "data.csv";
  if (fs::exists(imu, ec)) {
    auto r = read_euroc_imu_csv(imu.string());
    if (!r) return make_error(where, strip_function(r.error().message));
    s->imu_ = std::move(*r);
  }
  return s;
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
