// SinkFolder (sink_folder.hpp).
#include "pipeline/sinks/sink_folder.hpp"

#include <filesystem>
#include <fstream>

#include <opencv2/imgcodecs.hpp>

namespace fs = std::filesystem;

namespace augrig::pipeline {

std::string SinkFolder::path(const std::string& rel) const {
  return (fs::path(dir_) / rel).string();
}

Status SinkFolder::create(const std::vector<std::string>& subfolders, const std::string& until) const {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  for (const std::string& s : subfolders)
    if (!ec) fs::create_directories(fs::path(dir_) / s, ec);
  if (ec) return make_error(who_, ": ", dir_, ": cannot create the folder: ", ec.message());
  return write_text("INCOMPLETE", "written by augrig; " + until + "\n");
}

void SinkFolder::complete() const {
  std::error_code ec;
  fs::remove(fs::path(dir_) / "INCOMPLETE", ec);
}

Status SinkFolder::ensure_parent(const std::string& rel) const {
  const fs::path parent = (fs::path(dir_) / rel).parent_path();
  std::error_code ec;
  fs::create_directories(parent, ec);
  if (ec) return make_error(who_, ": ", parent.string(), ": cannot create the folder: ", ec.message());
  return {};
}

Status SinkFolder::write_text(const std::string& rel, const std::string& text) const {
  if (Status s = ensure_parent(rel); !s) return s;
  const std::string p = path(rel);
  std::ofstream out(p, std::ios::binary);
  out << text;
  out.close();
  if (!out) return make_error(who_, ": ", p, ": cannot write the file");
  return {};
}

Status SinkFolder::write_image(const std::string& rel, const cv::Mat& image,
                               const std::vector<int>& params) const {
  if (Status s = ensure_parent(rel); !s) return s;
  const std::string p = path(rel);
  bool ok = false;
  try {
    ok = cv::imwrite(p, image, params);
  } catch (const cv::Exception& e) {
    return make_error(who_, ": ", p, ": ", e.what());
  }
  if (!ok) return make_error(who_, ": ", p, ": cannot write the file");
  return {};
}

Status SinkFolder::link(const std::string& from, const std::string& to) const {
  if (Status s = ensure_parent(to); !s) return s;
  const fs::path a = fs::path(dir_) / from, b = fs::path(dir_) / to;
  std::error_code ec;
  fs::create_hard_link(a, b, ec);
  if (ec) fs::copy_file(a, b, fs::copy_options::overwrite_existing, ec);
  if (ec) return make_error(who_, ": ", b.string(), ": cannot write the file: ", ec.message());
  return {};
}

}  // namespace augrig::pipeline
