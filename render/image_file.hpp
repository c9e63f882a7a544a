// Image files in augrig's pixel formats, through OpenCV: reads 8-bit gray, BGR and BGRA files
// (gray as Mono8 or a given Bayer pattern); writes lossless PNG, converting RGB(A) to OpenCV's
// BGR(A) order into a buffer of its own (the caller's pixels stay unchanged). Mono8 and the Bayer
// formats are written as 8-bit gray.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "core/expected.hpp"
#include "core/image.hpp"

namespace augrig {

// Reads an image file as augrig's formats: 8-bit gray -> Mono8 (or `bayer` when given), BGR ->
// RGB8, BGRA -> RGBA8. Any other depth or channel count, or an unreadable file, is an Error naming
// it ("PATH: has 16-bit samples; expected ...").
Expected<Image> read_image_file(const std::string& path, std::optional<PixelFormat> bayer = std::nullopt);

// Errors name the file. The folder must exist.
Status write_png_file(const std::string& path, const Image& image, int compression = 1);

// A JPEG file's bytes in memory (libjpeg-turbo through OpenCV), at `quality` 1..100: colour as
// colour, a Bayer mosaic demosaiced to colour first (compressing the mosaic itself would smear
// its colours together), Mono8 as gray. For the live view's compressed topics.
Expected<std::vector<std::uint8_t>> encode_jpeg(ConstImageView image, int quality);

}  // namespace augrig
