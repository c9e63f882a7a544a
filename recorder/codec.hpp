// codec: how a recording stores images, losslessly (docs/RECORDING.md, "Blob encodings").
//
//   raw image   rows packed tight, each byte replaced by its difference (mod 256) from the byte
//               `predictor_distance(format)` to its left in the same row (the same colour site of
//               a Bayer mosaic, the same channel of RGB8/RGBA8, the left neighbour of Mono8; the
//               first bytes of each row as they are), then one zstd frame with its content size
//               and content checksum.
//   mask        the Mono8 bytes, rows packed tight, as one zstd frame.
//   augmented   the augmented image XOR the raw image inside `ChangedBox`, the smallest box holding
//               every byte where they differ (rows of the box packed tight), as one zstd frame;
//               outside the box the augmented image is the raw image. No change: an empty box and
//               an empty blob.
//   depth       float32 values of a box (the receiver depth inside the box outside which it is
//               +inf: record.hpp DepthRecord), rows packed tight: each value's IEEE bits as a uint32
//               replaced by its difference (mod 2^32) from the value to its left in the same row
//               (the first of a row as it is), then split into four byte planes (all low bytes,
//               ..., all high bytes), as one zstd frame. An empty box: an empty blob.
//
// Every decode checks the frame's content size against the image size and the zstd checksum, so
// a damaged blob is an error, never a silently wrong image.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>
#include <vector>

#include "core/expected.hpp"
#include "core/image.hpp"

typedef struct ZSTD_CCtx_s ZSTD_CCtx;
typedef struct ZSTD_DCtx_s ZSTD_DCtx;

namespace augrig::recorder {

// The raw encoding's one-line description, stored as the recording's meta `codec.raw`: a stored raw
// blob may be copied into a new recording only when its recording says the same.
inline constexpr std::string_view kRawCodec =
    "zstd frame of the row-delta residuals: r[x] = p[x] - p[x-d] mod 256, d = 2 Bayer, "
    "1 Mono8, 3 RGB8, 4 RGBA8; rows packed tight";

// The depth encoding's one-line description (meta `codec.depth`).
inline constexpr std::string_view kDepthCodec =
    "zstd frame of the float32 depth inside [x0,x1) x [y0,y1) (+inf outside), rows packed tight: "
    "uint32 bits, r[x] = b[x] - b[x-1] mod 2^32 per row, as 4 byte planes (low byte first)";

// A cheap identity of an image's pixels: a 64-bit hash of its size, format and every 8th row
// (from row 0), about 1/8 of the bytes. Equal images give equal fingerprints; it tells a frame
// from another frame and catches edits that span 8 rows or more, not every changed byte.
std::uint64_t raw_fingerprint(ConstImageView image);

// Bytes between a byte and its predictor: 2 for Bayer, 1 for Mono8, 3 for RGB8, 4 for RGBA8.
int predictor_distance(PixelFormat format);

// [x0, x1) x [y0, y1) in pixels.
using ChangedBox = PixelBox;

// The smallest box holding every pixel where `a` and `b` differ in any byte (empty if none).
// Both must have the same size and format.
ChangedBox changed_box(ConstImageView a, ConstImageView b);

// One per thread: holds a zstd context and scratch memory, reused from call to call.
class Encoder {
 public:
  explicit Encoder(int zstd_level = 1);
  ~Encoder();
  Encoder(const Encoder&) = delete;
  Encoder& operator=(const Encoder&) = delete;

  // `out` is replaced by the blob.
  Status encode_image(ConstImageView image, std::vector<std::uint8_t>& out);
  Status encode_mask(ConstImageView mask, std::vector<std::uint8_t>& out);
  // `raw` and `augmented`: same size and format. Sets `box`; `out` is empty when nothing changed.
  Status encode_difference(ConstImageView raw, ConstImageView augmented, ChangedBox& box,
                           std::vector<std::uint8_t>& out);
  // The same blob from the augmented image's part inside `within` (`part`, of that box's size;
  // outside it the augmented image is `raw`), as the augmenter's changed-box output gives it:
  // only the box is compared, no whole image is needed.
  Status encode_difference(ConstImageView raw, ConstImageView part, const PixelBox& within, ChangedBox& box,
                           std::vector<std::uint8_t>& out);
  // `width` x `height` float32 values, row-major (the depth encoding); `out` is empty for none.
  Status encode_depth(const float* values, int width, int height, std::vector<std::uint8_t>& out);

 private:
  Status compress(const std::uint8_t* src, std::size_t n, std::vector<std::uint8_t>& out);
  ZSTD_CCtx* cctx_ = nullptr;
  std::vector<std::uint8_t> scratch_;
  std::vector<std::uint8_t> compressed_;  // zstd's output, at its bound size, kept between calls
};

// One per thread. Errors say what is wrong with the blob ("zstd: ...", "holds N bytes, expected M");
// the caller adds which file, frame and image.
class Decoder {
 public:
  Decoder();
  ~Decoder();
  Decoder(const Decoder&) = delete;
  Decoder& operator=(const Decoder&) = delete;

  Status decode_image(const std::uint8_t* blob, std::size_t n, int width, int height, PixelFormat format,
                      Image& out);
  Status decode_mask(const std::uint8_t* blob, std::size_t n, int width, int height, Image& out);
  // `out` = `raw` with the box XORed back.
  Status decode_difference(const std::uint8_t* blob, std::size_t n, const ChangedBox& box, const Image& raw,
                           Image& out);
  // `out` = the `width` x `height` values (an empty blob for 0 x 0).
  Status decode_depth(const std::uint8_t* blob, std::size_t n, int width, int height,
                      std::vector<float>& out);

 private:
  Status decompress(const std::uint8_t* blob, std::size_t n, std::uint8_t* dst, std::size_t expected);
  ZSTD_DCtx* dctx_ = nullptr;
  std::vector<std::uint8_t> scratch_;
};

}  // namespace augrig::recorder
