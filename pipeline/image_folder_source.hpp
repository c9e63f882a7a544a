// ImageFolderSource (files://): a FrameSource that plays a sequence of image files of both cameras,
// in time order, as a finite, lockstep source (nothing is dropped, however slow the reader).
//
// Two ways to name the files:
//   an index   the frame index CSV `augrig sim` writes and `augrig nav` reads (nav/logs.hpp:
//              sequence,camera,t_ns,file; the files relative to the index's folder). Each Frame
//              carries the row's t_ns on the index's clock (`# clock:`, device by default), its
//              camera and sequence; the pipeline pairs left and right by timestamp.
//   folders    a left and a right folder (or two single image files), paired by sorted file name as
//              `augrig augment` always did: the i-th pair's frames both get t_ns = sequence = i and
//              are delivered left then right (PairingMode::kAdjacent).
// Every file is checked to exist when the source opens; an error names the index's file and line.
// Images are read with read_image_file (render/image_file.hpp), gray ones as `bayer` when given.
// Each Frame's attachment is an ImageFileAttachment naming its file (e.g. for output names).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/expected.hpp"
#include "core/frame.hpp"
#include "core/image.hpp"

namespace augrig::pipeline {

// One image of the sequence.
struct ImageFolderEntry {
  CameraId camera = CameraId::kLeft;
  std::uint64_t sequence = 0;
  TimestampNs t_ns = 0;
  std::string path;      // as opened (the index's folder joined with its `file`)
  std::size_t line = 0;  // the index's line (1-based); 0 for folders
};

// What a delivered Frame came from.
struct ImageFileAttachment final : FrameAttachment {
  std::string path;
  std::size_t line = 0;  // the index's line; 0 for folders
  std::string file_path() const override { return path; }
};

struct ImageFolderOptions {
  std::optional<PixelFormat> bayer;  // gray images are raw mosaics of this pattern
  std::string uri;                   // what uri() says (default: files://INDEX or files://folders?left=..&right=..)
};

class ImageFolderSource final : public FrameSource {
 public:
  // The frames of a frame index CSV. Errors: the index's own (file:line), a camera other than 0 or
  // 1, a file that does not exist ("INDEX:LINE: file 'left/000012.png' (camera 0, sequence 12): no
  // such file"), no frame of one camera.
  static Expected<std::unique_ptr<ImageFolderSource>> open_index(const std::string& index_path,
                                                                 const ImageFolderOptions& options = {});
  // Two folders of images (.png .jpg .jpeg .tif .tiff .bmp .pgm .ppm .pnm) paired by sorted name, the
  // counts equal; or two image files (one pair).
  static Expected<std::unique_ptr<ImageFolderSource>> open_folders(const std::string& left, const std::string& right,
                                                                   const ImageFolderOptions& options = {});

  std::string uri() const override { return uri_; }
  Expected<ReadStatus> read(Frame& out, std::chrono::nanoseconds timeout) override;
  SourceCapabilities capabilities() const override { return {.finite = true}; }
  // The pairs the pairing tolerance the source was opened with forms (expected_pairs()).
  std::size_t pair_count() const override { return expected_pairs(pairing_tolerance_ns_); }
  std::size_t image_count() const override { return entries_.size(); }
  void set_pairing_tolerance(TimestampNs tolerance_ns) { pairing_tolerance_ns_ = tolerance_ns; }

  // Every image, in delivery order (by t_ns; folders: left then right per pair).
  const std::vector<ImageFolderEntry>& entries() const { return entries_; }
  bool from_index() const { return index_.size() > 0; }
  const std::string& index_path() const { return index_; }
  ClockDomain clock() const { return clock_; }
  // Half the median interval between consecutive frames of one camera (the default pairing
  // tolerance); 0 when no camera has two frames.
  TimestampNs half_median_interval_ns() const;
  // The pairs timestamp pairing within `tolerance_ns` forms (each left frame with the nearest
  // unused right one within the tolerance, in time order): the progress total. Folders: the count.
  std::size_t expected_pairs(TimestampNs tolerance_ns) const;
  // "INDEX:LINE (camera 0, sequence 12)", or the file's path for folders: where a frame came from.
  std::string where(const ImageFolderEntry& e) const;

 private:
  ImageFolderSource() = default;
  std::string uri_, index_;
  std::optional<PixelFormat> bayer_;
  ClockDomain clock_ = ClockDomain::kUnknown;
  std::vector<ImageFolderEntry> entries_;
  std::size_t next_ = 0;
  TimestampNs pairing_tolerance_ns_ = 0;
};

}  // namespace augrig::pipeline
