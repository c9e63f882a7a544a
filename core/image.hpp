// Image: an owning 2D pixel buffer with an explicit pixel format and row stride, and ImageView,
// a non-owning view of one. Bayer mosaics stay Bayer: the format names the colour of the
// top-left 2x2 cell in reading order (kBayerRG8 = R G / G B), as GenICam PFNC does.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>
#include <vector>

namespace augrig {

enum class PixelFormat : std::uint8_t {
  kMono8,
  kRGB8,
  kRGBA8,
  kBayerRG8,
  kBayerGR8,
  kBayerGB8,
  kBayerBG8,
};

constexpr int bytes_per_pixel(PixelFormat f) {
  switch (f) {
    case PixelFormat::kRGB8:
      return 3;
    case PixelFormat::kRGBA8:
      return 4;
    default:
      return 1;
  }
}
constexpr bool is_bayer(PixelFormat f) {
  return f == PixelFormat::kBayerRG8 || f == PixelFormat::kBayerGR8 || f == PixelFormat::kBayerGB8 ||
         f == PixelFormat::kBayerBG8;
}
constexpr std::string_view to_string(PixelFormat f) {
  switch (f) {
    case PixelFormat::kMono8:
      return "Mono8";
    case PixelFormat::kRGB8:
      return "RGB8";
    case PixelFormat::kRGBA8:
      return "RGBA8";
    case PixelFormat::kBayerRG8:
      return "BayerRG8";
    case PixelFormat::kBayerGR8:
      return "BayerGR8";
    case PixelFormat::kBayerGB8:
      return "BayerGB8";
    case PixelFormat::kBayerBG8:
      return "BayerBG8";
  }
  return "?";
}
// Parses the GenICam PFNC names above; returns false for anything else.
bool parse_pixel_format(std::string_view name, PixelFormat& out);

// Colour channel (0 = R, 1 = G, 2 = B) sampled by the Bayer site at (x, y).
constexpr int bayer_channel(PixelFormat f, int x, int y) {
  const int cell = ((y & 1) << 1) | (x & 1);  // 0 1 / 2 3
  constexpr int kRG[4] = {0, 1, 1, 2};
  constexpr int kGR[4] = {1, 0, 2, 1};
  constexpr int kGB[4] = {1, 2, 0, 1};
  constexpr int kBG[4] = {2, 1, 1, 0};
  switch (f) {
    case PixelFormat::kBayerRG8:
      return kRG[cell];
    case PixelFormat::kBayerGR8:
      return kGR[cell];
    case PixelFormat::kBayerGB8:
      return kGB[cell];
    case PixelFormat::kBayerBG8:
      return kBG[cell];
    default:
      return -1;
  }
}

// Non-owning view; `stride_bytes` >= width * bytes_per_pixel(format).
template <typename Byte>
struct BasicImageView {
  Byte* data = nullptr;
  int width = 0;
  int height = 0;
  std::size_t stride_bytes = 0;
  PixelFormat format = PixelFormat::kMono8;

  Byte* row(int y) const { return data + static_cast<std::size_t>(y) * stride_bytes; }
  bool empty() const { return data == nullptr || width <= 0 || height <= 0; }
};
using ImageView = BasicImageView<std::uint8_t>;
using ConstImageView = BasicImageView<const std::uint8_t>;

// A box of pixels, [x0, x1) x [y0, y1).
struct PixelBox {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  bool empty() const { return x1 <= x0 || y1 <= y0; }
  int width() const { return empty() ? 0 : x1 - x0; }
  int height() const { return empty() ? 0 : y1 - y0; }
  // Whether it lies in a width x height image (an empty box lies anywhere).
  bool inside(int width, int height) const {
    return empty() || (x0 >= 0 && y0 >= 0 && x1 <= width && y1 <= height);
  }
  friend bool operator==(const PixelBox&, const PixelBox&) = default;
};

// The part of `v` inside `box` (which must lie in it).
template <typename Byte>
BasicImageView<Byte> sub_view(const BasicImageView<Byte>& v, const PixelBox& box) {
  return {v.data + static_cast<std::size_t>(box.y0) * v.stride_bytes +
              static_cast<std::size_t>(box.x0) * static_cast<std::size_t>(bytes_per_pixel(v.format)),
          box.width(), box.height(), v.stride_bytes, v.format};
}

class Image {
 public:
  Image() = default;
  Image(int width, int height, PixelFormat format, std::size_t stride_bytes = 0);

  int width() const { return width_; }
  int height() const { return height_; }
  PixelFormat format() const { return format_; }
  std::size_t stride_bytes() const { return stride_; }
  bool empty() const { return width_ == 0 || height_ == 0; }
  std::uint8_t* data() { return bytes_.data(); }
  const std::uint8_t* data() const { return bytes_.data(); }
  std::size_t size_bytes() const { return bytes_.size(); }
  std::uint8_t* row(int y) { return bytes_.data() + static_cast<std::size_t>(y) * stride_; }
  const std::uint8_t* row(int y) const { return bytes_.data() + static_cast<std::size_t>(y) * stride_; }

  ImageView view() { return {data(), width_, height_, stride_, format_}; }
  ConstImageView view() const { return {data(), width_, height_, stride_, format_}; }
  ConstImageView cview() const { return view(); }

  // Deep copy of a view (rows repacked to the tightest stride).
  static Image copy_of(ConstImageView v);

  // Makes this a width x height image of `format`, tightly strided, keeping the buffer's
  // capacity: an image whose size changes every frame reallocates only when it grows. Pixel
  // values are unspecified afterwards.
  void reshape(int width, int height, PixelFormat format);

  // True when sizes, formats and every pixel byte match (padding bytes are ignored).
  friend bool pixels_equal(const Image& a, const Image& b);

 private:
  std::vector<std::uint8_t> bytes_;
  int width_ = 0;
  int height_ = 0;
  std::size_t stride_ = 0;
  PixelFormat format_ = PixelFormat::kMono8;
};

}  // namespace augrig
