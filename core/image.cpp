#include "core/image.hpp"

#include <algorithm>
#include <cstring>

namespace augrig {

bool parse_pixel_format(std::string_view name, PixelFormat& out) {
  for (PixelFormat f : {PixelFormat::kMono8, PixelFormat::kRGB8, PixelFormat::kRGBA8, PixelFormat::kBayerRG8,
                        PixelFormat::kBayerGR8, PixelFormat::kBayerGB8, PixelFormat::kBayerBG8}) {
    if (name == to_string(f)) {
      out = f;
      return true;
    }
  }
  return false;
}

Image::Image(int width, int height, PixelFormat format, std::size_t stride_bytes)
    : width_(std::max(width, 0)), height_(std::max(height, 0)), format_(format) {
  const std::size_t tight = static_cast<std::size_t>(width_) * bytes_per_pixel(format);
  stride_ = std::max(stride_bytes, tight);
  bytes_.assign(stride_ * static_cast<std::size_t>(height_), 0);
}

void Image::reshape(int width, int height, PixelFormat format) {
  width_ = std::max(width, 0), height_ = std::max(height, 0), format_ = format;
  stride_ = static_cast<std::size_t>(width_) * bytes_per_pixel(format);
  bytes_.resize(stride_ * static_cast<std::size_t>(height_));  // never shrinks the capacity
}

Image Image::copy_of(ConstImageView v) {
  Image img(v.width, v.height, v.format);
  const std::size_t row_bytes = static_cast<std::size_t>(v.width) * bytes_per_pixel(v.format);
  for (int y = 0; y < v.height; ++y) std::memcpy(img.row(y), v.row(y), row_bytes);
  return img;
}

bool pixels_equal(const Image& a, const Image& b) {
  if (a.width_ != b.width_ || a.height_ != b.height_ || a.format_ != b.format_) return false;
  const std::size_t row_bytes = static_cast<std::size_t>(a.width_) * bytes_per_pixel(a.format_);
  for (int y = 0; y < a.height_; ++y)
    if (std::memcmp(a.row(y), b.row(y), row_bytes) != 0) return false;
  return true;
}

}  // namespace augrig
