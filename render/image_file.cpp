#include "render/image_file.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace augrig {

Status write_png_file(const std::string& path, const Image& image, int compression) {
  if (image.empty()) return make_error(path, ": nothing to write (empty image)");
  const int channels = bytes_per_pixel(image.format());
  const cv::Mat m(image.height(), image.width(), CV_8UC(channels), const_cast<std::uint8_t*>(image.data()),
                  image.stride_bytes());
  cv::Mat bgr;
  if (image.format() == PixelFormat::kRGB8)
    cv::cvtColor(m, bgr, cv::COLOR_RGB2BGR);
  else if (image.format() == PixelFormat::kRGBA8)
    cv::cvtColor(m, bgr, cv::COLOR_RGBA2BGRA);
  else
    bgr = m;
  try {
    if (!cv::imwrite(path, bgr, {cv::IMWRITE_PNG_COMPRESSION, compression}))
      return make_error(path, ": cannot write the image");
  } catch (const cv::Exception& e) {
    return make_error(path, ": cannot write the image (", e.what(), ")");
  }
  return {};
}

}  // namespace augrig
