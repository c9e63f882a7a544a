// core/png: augrig's own PNG writer (8-bit gray, RGB, RGBA), on zlib. It exists because PNG
// encoding is what an export costs (bench/bench_png, bench/bench_export, docs/PERFORMANCE.md):
// OpenCV's writer tries libpng's adaptive filters on every row and cannot reuse work between two
// images that differ in a few rows (a raw image and its augmented copy).
//
// Rows go in bands of kPngBandRows, each band its own raw-deflate segment that ends byte-aligned
// (Z_SYNC_FLUSH) and refers to nothing before it (Huffman-only or stored coding, or a deflateReset
// per band). So an augmented image reuses the raw image's segments for every band whose rows it
// did not change, and only the bands the boom touches are compressed again. Filters: Sub
// (row-local, so a band depends on its own rows only) for images, Up for masks (whose rows
// repeat); none when stored. Every setting is lossless; any PNG reader decodes the files.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/expected.hpp"
#include "core/image.hpp"

namespace augrig {

constexpr int kPngBandRows = 32;

// kImage: Sub filter, bands reusable; kMask: Up filter, run-length coded at compression 1.
enum class PngKind { kImage, kMask };

struct PngBand {
  std::string bytes;  // raw deflate, byte-aligned, not final
  std::uint32_t adler = 1;
  std::size_t length = 0;  // filtered bytes in
};

// An encoded image before it is wrapped into a file (png_file()).
struct PngImage {
  int width = 0, height = 0, channels = 1;
  std::vector<PngBand> bands;
};

// One zlib stream reused from image to image: one encoder per thread.
class PngEncoder {
 public:
  // `compression`: 0 stored (fastest, largest), 1 fast (Huffman coding of the Sub-filtered rows;
  // masks run-length coded), 2..9 zlib's levels. Clamped to 0..9.
  PngEncoder(int compression, PngKind kind);
  ~PngEncoder();
  PngEncoder(const PngEncoder&) = delete;
  PngEncoder& operator=(const PngEncoder&) = delete;

  // Encodes `image` (8 bits a sample, 1, 3 or 4 channels); with `reuse` (an encoding of an image
  // of the same size, format and kind), the bands whose rows equal `reuse_pixels`'s are taken from
  // it rather than compressed again.
  Expected<PngImage> encode(const Image& image, const PngImage* reuse = nullptr,
                            const Image* reuse_pixels = nullptr);

 private:
  bool band_reusable(const Image& image, const Image& reuse_pixels, int y0, int y1) const;
  void filter_band(const Image& image, int y0, int y1, std::size_t row_bytes, std::size_t bpp);
  Status deflate_band(PngBand& band, bool reset);

  PngKind kind_;
  int filter_ = 1;
  bool reset_each_band_ = false;
  struct Stream;
  Stream* z_ = nullptr;  // zlib's z_stream, kept out of this header
  bool ok_ = false;
  std::vector<std::uint8_t> filtered_;
};

// The PNG file: signature, IHDR (8-bit gray, RGB or RGBA), IDAT (a zlib stream: header, the
// bands, an empty final block, the Adler-32 of every filtered byte), IEND.
std::string png_file(const PngImage& image);

// `bytes` written to `path` (created or truncated); errors name the file and errno's text.
Status write_binary_file(const std::string& path, const std::string& bytes);

}  // namespace augrig
