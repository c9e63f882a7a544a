#include "render/image_file.hpp"

#include <algorithm>
#include <filesystem>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "render/cv_image.hpp"

namespace augrig {

Expected<Image> read_image_file(const std::string& path, std::optional<PixelFormat> bayer) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return make_error(path, ": no such file");
  if (std::filesystem::is_directory(path, ec)) return make_error(path, ": is a folder, expected an image file");
  cv::Mat m;
  try {
    m = cv::imread(path, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    return make_error(path, ": cannot decode the image (", e.what(), ")");
  }
  if (m.empty())
    return make_error(path, ": cannot read the image (unreadable, corrupt or not an image format)");
  const char* expected = "expected an 8-bit image: gray (Mono8 or a Bayer mosaic), BGR or BGRA";
  if (m.depth() != CV_8U) {
    const int bits = m.depth() == CV_16U || m.depth() == CV_16S ? 16 : (m.depth() == CV_8S ? 8 : 32);
    return make_error(path, ": has ", bits, "-bit samples; ", expected);
  }
  PixelFormat format;
  cv::Mat rgb;
  switch (m.channels()) {
    case 1:
      format = bayer ? *bayer : PixelFormat::kMono8;
      break;
    case 3:
      if (bayer) return make_error(path, ": has 3 channels, but a Bayer pattern (--bayer) expects 8-bit gray raw mosaics");
      format = PixelFormat::kRGB8;
      cv::cvtColor(m, rgb, cv::COLOR_BGR2RGB);  // OpenCV reads BGR
      m = rgb;
      break;
    case 4:
      if (bayer) return make_error(path, ": has 4 channels, but a Bayer pattern (--bayer) expects 8-bit gray raw mosaics");
      format = PixelFormat::kRGBA8;
      cv::cvtColor(m, rgb, cv::COLOR_BGRA2RGBA);
      m = rgb;
      break;
    default:
      return make_error(path, ": has ", m.channels(), " channels; ", expected);
  }
  Image im(m.cols, m.rows, format);
  const std::size_t row_bytes = static_cast<std::size_t>(m.cols) * bytes_per_pixel(format);
  for (int y = 0; y < m.rows; ++y) std::copy_n(m.ptr<std::uint8_t>(y), row_bytes, im.row(y));
  return im;
}

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

Expected<std::vector<std::uint8_t>> encode_jpeg(ConstImageView image, int quality) {
  if (image.empty()) return make_error("encode_jpeg(): nothing to encode (empty image)");
  if (quality < 1 || quality > 100) return make_error("encode_jpeg(): quality ", quality, ": expected 1..100");
  std::vector<std::uint8_t> out;
  try {
    if (!cv::imencode(".jpg", bgr_of(image), out, {cv::IMWRITE_JPEG_QUALITY, quality}))
      return make_error("encode_jpeg(): OpenCV could not encode the image");
  } catch (const cv::Exception& e) {
    return make_error("encode_jpeg(): ", e.what());
  }
  return out;
}

}  // namespace augrig
