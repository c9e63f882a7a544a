// Lossless image files: writes augrig's pixel formats as PNG through OpenCV, converting RGB(A) to
// OpenCV's BGR(A) order into a buffer of its own (the caller's pixels stay unchanged). Mono8 and
// the Bayer formats are written as 8-bit gray.
#pragma once

#include <string>

#include "core/expected.hpp"
#include "core/image.hpp"

namespace augrig {

// Errors name the file. The folder must exist.
Status write_png_file(const std::string& path, const Image& image, int compression = 1);

}  // namespace augrig
