// cv_image: augrig's images as OpenCV matrices for the matchers and the file writers: 8-bit gray
// (what a stereo matcher takes) or BGR (what cv::imwrite writes as colour), Bayer demosaiced.
// GenICam (PFNC) names a Bayer pattern by its top-left 2x2 cell, OpenCV one row and one column on
// (render/visualize.cpp): PFNC's BayerRG is OpenCV's BayerBG.
#pragma once

#include <opencv2/core.hpp>

#include "core/image.hpp"

namespace augrig {

// An OpenCV header over the image's own pixels (no copy; CV_8UC1, 3 or 4 by its format, Bayer as
// its mosaic), valid while the image is.
cv::Mat cv_view(ConstImageView image);

// An image of augrig's formats as 8-bit gray (CV_8UC1, its own buffer): Bayer demosaiced
// (OpenCV's bilinear), RGB(A) weighted as OpenCV's cvtColor, Mono8 copied.
cv::Mat gray_of(ConstImageView image);

// An image of augrig's formats as an 8-bit image OpenCV writes as it is: Mono8 gray (CV_8UC1),
// colour and Bayer as BGR (CV_8UC3; Bayer demosaiced, OpenCV's bilinear).
cv::Mat bgr_of(ConstImageView image);

}  // namespace augrig
