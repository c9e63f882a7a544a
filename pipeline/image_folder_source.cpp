#include "pipeline/image_folder_source.hpp"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>

#include "nav/logs.hpp"
#include "render/image_file.hpp"

namespace augrig::pipeline {
namespace {

namespace fs = std::filesystem;

const char* kOpen = "pipeline::ImageFolderSource::open(): ";

bool is_image_name(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char ch) { return std::tolower(ch); });
  for (const char* e : {".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".pgm", ".ppm", ".pnm"})
    if (ext == e) return true;
  return false;
}

// The line number of each data row of a CSV read by nav/logs (blank and '#' lines skipped, the
// first other line the header), so that a row's problem can name its line.
std::vector<std::size_t> data_lines(const std::string& path) {
  std::vector<std::size_t> lines;
  std::ifstream in(path);
  bool header = true;
  std::size_t n = 0;
  for (std::string text; std::getline(in, text);) {
    ++n;
    const auto first = text.find_first_not_of(" \t\r\n");
    if (first == std::string::npos || text[first] == '#') continue;
    if (header) {
      header = false;
      continue;
    }
    lines.push_back(n);
  }
  return lines;
}

Expected<std::vector<fs::path>> list_images(const std::string& dir) {
  std::vector<fs::path> files;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec))
    if (entry.is_regular_file() && is_image_name(entry.path())) files.push_back(entry.path());
  if (ec) return make_error(kOpen, dir, ": cannot list the folder (", ec.message(), ")");
  std::sort(files.begin(), files.end(),
            [](const fs::path& a, const fs::path& b) { return a.filename().string() < b.filename().string(); });
  return files;
}

}  // namespace

Expected<std::unique_ptr<ImageFolderSource>> ImageFolderSource::open_index(const std::string& index_path,
                                                                           const ImageFolderOptions& options) {
  auto index = nav::read_frame_index_csv(index_path);
  if (!index) return index.error();
  std::unique_ptr<ImageFolderSource> s(new ImageFolderSource());
  s->uri_ = options.uri.empty() ? "files://" + index_path : options.uri;
  s->index_ = index_path;
  s->bayer_ = options.bayer;
  s->clock_ = index->clock;
  const std::vector<std::size_t> lines = data_lines(index_path);
  const fs::path dir = fs::path(index_path).parent_path();
  std::size_t per_camera[2] = {0, 0};
  for (std::size_t i = 0; i < index->rows.size(); ++i) {
    const nav::FrameIndexRow& r = index->rows[i];
    const std::size_t line = i < lines.size() ? lines[i] : 0;
    if (r.camera != 0 && r.camera != 1)
      return make_error(kOpen, index_path, ":", line, ": column 'camera': expected 0 (left) or 1 (right) of a stereo rig, got ",
                        r.camera);
    ImageFolderEntry e;
    e.camera = r.camera == 0 ? CameraId::kLeft : CameraId::kRight;
    e.sequence = r.sequence;
    e.t_ns = r.t_ns;
    e.path = (dir / r.file).string();
    e.line = line;
    // Every file is looked for now: a missing one fails before anything is augmented.
    std::error_code ec;
    if (!fs::is_regular_file(e.path, ec))
      return make_error(kOpen, index_path, ":", line, ": file '", r.file, "' (camera ", r.camera, ", sequence ",
                        r.sequence, "): ", fs::exists(e.path, ec) ? "not a regular file" : "no such file", " (",
                        e.path, ")");
    ++per_camera[r.camera];
    s->entries_.push_back(std::move(e));
  }
  for (int c = 0; c < 2; ++c)
    if (per_camera[c] == 0)
      return make_error(kOpen, index_path, ": no frame of camera ", c, c == 0 ? " (left)" : " (right)",
                        "; a stereo sequence needs both");
  // Delivery in time order, so that the pairer sees each frame's partner next to it. The index's rows
  // increase per camera; the cameras may interleave in any order there.
  std::stable_sort(s->entries_.begin(), s->entries_.end(),
                   [](const ImageFolderEntry& a, const ImageFolderEntry& b) { return a.t_ns < b.t_ns; });
  return s;
}

Expected<std::unique_ptr<ImageFolderSource>> ImageFolderSource::open_folders(const std::string& left,
                                                                             const std::string& right,
                                                                             const ImageFolderOptions& options) {
  std::unique_ptr<ImageFolderSource> s(new ImageFolderSource());
  s->uri_ = options.uri.empty() ? "files://folders?left=" + left + "&right=" + right : options.uri;
  s->bayer_ = options.bayer;
  std::error_code ec;
  const bool ldir = fs::is_directory(left, ec), rdir = fs::is_directory(right, ec);
  if (ldir != rdir)
    return make_error(kOpen, "left and right must both be image files or both folders (", left, " is ",
                      ldir ? "a folder" : "not a folder", ", ", right, " is ", rdir ? "a folder" : "not a folder", ")");
  std::vector<fs::path> lf, rf;
  if (ldir) {
    auto l = list_images(left), r = list_images(right);
    if (!l) return l.error();
    if (!r) return r.error();
    lf = std::move(*l);
    rf = std::move(*r);
    if (lf.size() != rf.size())
      return make_error(kOpen, "the image folders differ in count: ", left, " has ", lf.size(), ", ", right, " has ",
                        rf.size(), " image(s); pairs are formed by sorted name");
    if (lf.empty()) return make_error(kOpen, left, ": no images (.png .jpg .tif .bmp .pgm .ppm) in the folder");
  } else {
    // Two files: one pair. A missing one is named as read_image_file names it.
    for (const std::string& f : {left, right})
      if (!fs::exists(f, ec)) return make_error(kOpen, f, ": no such file");
    lf = {left};
    rf = {right};
  }
  for (std::size_t i = 0; i < lf.size(); ++i) {
    for (CameraId c : {CameraId::kLeft, CameraId::kRight}) {
      ImageFolderEntry e;
      e.camera = c;
      e.sequence = i;
      e.t_ns = static_cast<TimestampNs>(i);
      e.path = (c == CameraId::kLeft ? lf : rf)[i].string();
      s->entries_.push_back(std::move(e));
    }
  }
  return s;
}

Expected<ReadStatus> ImageFolderSource::read(Frame& out, std::chrono::nanoseconds) {
  if (next_ >= entries_.size()) return ReadStatus::kEndOfStream;
  const ImageFolderEntry& e = entries_[next_++];
  auto image = read_image_file(e.path, bayer_);
  if (!image) {
    // The image reader names the file; an index row is named too.
    if (!from_index()) return make_error("pipeline::ImageFolderSource::read(): ", image.error().message);
    return make_error("pipeline::ImageFolderSource::read(): ", where(e), ": ", image.error().message);
  }
  out = Frame{};
  out.image = std::move(*image);
  out.t_ns = e.t_ns;
  out.clock = clock_;
  out.sequence = e.sequence;
  out.camera = e.camera;
  auto a = std::make_shared<ImageFileAttachment>();
  a->path = e.path;
  a->line = e.line;
  out.attachment = std::move(a);
  return ReadStatus::kFrame;
}

TimestampNs ImageFolderSource::half_median_interval_ns() const {
  std::vector<TimestampNs> intervals;
  std::optional<TimestampNs> last[2];
  for (const ImageFolderEntry& e : entries_) {
    std::optional<TimestampNs>& l = last[index_of(e.camera)];
    if (l) intervals.push_back(e.t_ns - *l);
    l = e.t_ns;
  }
  if (intervals.empty()) return 0;
  std::nth_element(intervals.begin(), intervals.begin() + static_cast<std::ptrdiff_t>(intervals.size() / 2),
                   intervals.end());
  return intervals[intervals.size() / 2] / 2;
}

std::size_t ImageFolderSource::expected_pairs(TimestampNs tolerance_ns) const {
  if (!from_index()) return entries_.size() / 2;
  std::vector<TimestampNs> l, r;
  for (const ImageFolderEntry& e : entries_) (e.camera == CameraId::kLeft ? l : r).push_back(e.t_ns);
  std::size_t pairs = 0, j = 0;
  for (TimestampNs t : l) {
    while (j < r.size() && r[j] < t - tolerance_ns) ++j;  // rights too early for this left: unpaired
    if (j < r.size() && r[j] <= t + tolerance_ns) {
      ++pairs;
      ++j;
    }
  }
  return pairs;
}

std::string ImageFolderSource::where(const ImageFolderEntry& e) const {
  if (!from_index()) return e.path;
  return index_ + ":" + std::to_string(e.line) + " (camera " + std::to_string(index_of(e.camera)) + ", sequence " +
         std::to_string(e.sequence) + ")";
}

}  // namespace augrig::pipeline
