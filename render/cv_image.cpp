#include "render/cv_image.hpp"

#include <opencv2/imgproc.hpp>

namespace augrig {
namespace {

cv::Mat wrap(ConstImageView v, int type) {
  return cv::Mat(v.height, v.width, type, const_cast<std::uint8_t*>(v.data), v.stride_bytes);
}

// OpenCV's conversion of each format to gray and to BGR (Bayer: its pattern one cell on).
struct Codes {
  int to_gray, to_bgr;
};
Codes codes_of(PixelFormat f) {
  switch (f) {
    case PixelFormat::kRGB8:
      return {cv::COLOR_RGB2GRAY, cv::COLOR_RGB2BGR};
    case PixelFormat::kRGBA8:
      return {cv::COLOR_RGBA2GRAY, cv::COLOR_RGBA2BGR};
    case PixelFormat::kBayerRG8:
      return {cv::COLOR_BayerBG2GRAY, cv::COLOR_BayerBG2BGR};
    case PixelFormat::kBayerGR8:
      return {cv::COLOR_BayerGB2GRAY, cv::COLOR_BayerGB2BGR};
    case PixelFormat::kBayerGB8:
      return {cv::COLOR_BayerGR2GRAY, cv::COLOR_BayerGR2BGR};
    default:  // kBayerBG8
      return {cv::COLOR_BayerRG2GRAY, cv::COLOR_BayerRG2BGR};
  }
}

int cv_type_of(PixelFormat f) {
  return f == PixelFormat::kRGB8 ? CV_8UC3 : f == PixelFormat::kRGBA8 ? CV_8UC4 : CV_8UC1;
}

cv::Mat converted(ConstImageView image, bool gray) {
  cv::Mat out;
  if (image.empty()) return out;
  if (image.format == PixelFormat::kMono8) {
    wrap(image, CV_8UC1).copyTo(out);
    return out;
  }
  const Codes c = codes_of(image.format);
  cv::cvtColor(wrap(image, cv_type_of(image.format)), out, gray ? c.to_gray : c.to_bgr);
  return out;
}

}  // namespace

cv::Mat cv_view(ConstImageView image) {
  return wrap(image, cv_type_of(image.format));
}

cv::Mat gray_of(ConstImageView image) {
  return converted(image, true);
}

cv::Mat bgr_of(ConstImageView image) {
  return converted(image, false);
}

}  // namespace augrig
