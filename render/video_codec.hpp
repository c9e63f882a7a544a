// H.264 for image streams (FFmpeg's libavcodec: x264 to encode, its own decoder to decode), as
// Foxglove's CompressedVideo wants it (docs/LIVE_VIEW.md, docs/MCAP.md): each frame in one access
// unit in Annex B (start codes), no B-frames (a frame's unit is final when it comes out, none held
// back), an IDR keyframe with its SPS and PPS every gop_frames frames and whenever the caller asks
// (a new subscriber, a client that lost a frame). Colour: BT.709, limited range, 4:2:0; a Bayer
// mosaic is demosaiced first (compressing the mosaic itself would smear its colours), gray is coded
// with neutral chroma and decoded back to gray. 4:2:0 needs even sizes: an odd width or height is
// padded by repeating the last column or row, and the decoder crops to the size it is told.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/conventions.hpp"
#include "core/expected.hpp"
#include "core/image.hpp"

namespace augrig {

struct H264Options {
  int gop_frames = 30;               // an IDR at least this often (frames); 1: every frame
  int crf = 23;                      // x264's constant rate factor, 0 (lossless) .. 51
  int max_kbps = 0;                  // a cap on the bit rate (x264's VBV, one second's buffer); 0: none
  std::string preset = "superfast";  // x264's speed/size trade (ultrafast .. veryslow)
  int threads = 1;                   // x264's slice threads (zerolatency: no frame threads, no added delay)
};

// x264's speed presets, fastest first: "ultrafast, superfast, ..., veryslow".
bool is_x264_preset(const std::string& name);
std::string x264_preset_names();

// One frame's coded bytes.
struct H264AccessUnit {
  std::vector<std::uint8_t> data;  // Annex B NAL units; an IDR's begins with its SPS and PPS
  bool keyframe = false;
};

class H264Encoder {
 public:
  // For frames of width x height pixels (any size from 2x2; odd sizes padded as above). Errors:
  // "H264Encoder::create(): ..." with FFmpeg's words (no x264 in this FFmpeg, bad options).
  static Expected<std::unique_ptr<H264Encoder>> create(int width_px, int height_px,
                                                       const H264Options& options = {});
  ~H264Encoder();
  H264Encoder(const H264Encoder&) = delete;
  H264Encoder& operator=(const H264Encoder&) = delete;

  // The next frame (Mono8, RGB8, RGBA8 or Bayer, of the size given to create()); `t_ns` its time
  // (rate control only: frames may come at any pace). `keyframe`: make this one an IDR.
  Expected<H264AccessUnit> encode(ConstImageView image, TimestampNs t_ns, bool keyframe = false);

  int width() const { return width_; }
  int height() const { return height_; }
  std::uint64_t frames() const { return frames_; }

 private:
  struct Impl;
  H264Encoder() = default;
  std::unique_ptr<Impl> impl_;
  int width_ = 0, height_ = 0;
  std::uint64_t frames_ = 0;
};

class H264Decoder {
 public:
  static Expected<std::unique_ptr<H264Decoder>> create();
  ~H264Decoder();
  H264Decoder(const H264Decoder&) = delete;
  H264Decoder& operator=(const H264Decoder&) = delete;

  // One access unit, in stream order, to its picture: RGB8, or Mono8 where the chroma is neutral
  // throughout (a gray camera's stream); cropped to width x height when given (> 0). An Error for
  // damaged data, or before the stream's first keyframe ("no picture ...").
  Expected<Image> decode(const std::uint8_t* data, std::size_t size, int width_px = 0, int height_px = 0);

 private:
  struct Impl;
  H264Decoder() = default;
  std::unique_ptr<Impl> impl_;
};

}  // namespace augrig
