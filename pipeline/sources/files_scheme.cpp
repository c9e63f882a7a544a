// files://INDEX.csv[?tolerance_us=US&bayer=RG|GR|GB|BG]: the image files a frame index names,
// paired by timestamp within US (default: half the median frame interval).
// files://folders?left=DIR&right=DIR[&bayer=..]: two folders, or two image files, paired by sorted
// name ("folders" because a URI needs a target).
// Lockstep: every file is read, none dropped (pipeline/image_folder_source.hpp). The reader is
// OpenedSourceInfo::image_files, for its entries' names and places.
#include "pipeline/image_folder_source.hpp"
#include "pipeline/sources/schemes.hpp"

namespace augrig::pipeline {

Expected<OpenedSource> open_files(const SourceUri& u) {
  OpenedSource out;
  if (Status s = u.check_known({"left", "right", "bayer", "tolerance_us"}); !s) return s.error();
  ImageFolderOptions o;
  o.uri = u.text;
  if (u.has("bayer")) {
    auto f = bayer_param(u);
    if (!f) return f.error();
    o.bayer = *f;
  }
  out.options.lossless = true;
  if (u.target == "folders") {
    if (!u.has("left") || !u.has("right"))
      return uri_error(u, "expected files://INDEX.csv or files://folders?left=DIR&right=DIR");
    if (u.has("tolerance_us"))
      return uri_error(u, "tolerance_us: folders pair by sorted name, not by time (give an index for that)");
    auto src = ImageFolderSource::open_folders(u.get("left"), u.get("right"), o);
    if (!src) return src.error();
    // Each pair comes as its left Frame, then its right one.
    out.options.pairing.mode = PairingMode::kAdjacent;
    out.image_files = src->get();
    out.sources.push_back(std::move(*src));
    return out;
  }
  if (u.has("left") || u.has("right"))
    return uri_error(u, "left and right name folders without an index; an index names its own files");
  auto src = ImageFolderSource::open_index(u.target, o);
  if (!src) return src.error();
  // Default: half the median frame interval (a frame can never pair with its neighbour's partner);
  // without an interval (one frame per camera), the widest tolerance a rig allows.
  const TimestampNs half = (*src)->half_median_interval_ns();
  const double default_us = half > 0 ? static_cast<double>(half) / 1e3 : kMaxPairingToleranceUs;
  auto tol = u.get_number("tolerance_us", default_us, 0, kMaxPairingToleranceUs);
  if (!tol) return tol.error();
  StereoPairerConfig& p = out.options.pairing;
  p.mode = PairingMode::kTimestamp;
  p.tolerance_ns = static_cast<std::int64_t>(*tol * 1e3);
  (*src)->set_pairing_tolerance(p.tolerance_ns);
  p.device_clock_shared = true;  // one index, one clock: its t_ns compare directly
  out.image_files = src->get();
  out.sources.push_back(std::move(*src));
  return out;
}

}  // namespace augrig::pipeline
