// The recording blob decoders (recorder/codec.hpp) with the sizes a recording's row gives.
// Input: mode byte, width and height (u32 each, as a damaged row may say anything), format byte,
// for the difference a change box (4 x i16), then the blob. Mode bit 0x80: the blob is first
// compressed into a valid zstd frame, so that the decoders' paths past the frame checks run too.
#include <vector>

#include <zstd.h>

#include "fuzz/fuzz_common.hpp"
#include "recorder/codec.hpp"

using namespace augrig;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fuzz::Input input(data, size);
  const std::uint8_t mode = input.byte();
  const int width = static_cast<int>(input.value<std::uint32_t>());
  const int height = static_cast<int>(input.value<std::uint32_t>());
  static const PixelFormat kFormats[] = {
      PixelFormat::kMono8,    PixelFormat::kRGB8,     PixelFormat::kRGBA8,   PixelFormat::kBayerRG8,
      PixelFormat::kBayerGR8, PixelFormat::kBayerGB8, PixelFormat::kBayerBG8};
  const PixelFormat format = kFormats[input.byte() % 7];
  PixelBox box;
  box.x0 = input.value<std::int16_t>();
  box.y0 = input.value<std::int16_t>();
  box.x1 = input.value<std::int16_t>();
  box.y1 = input.value<std::int16_t>();
  const std::string_view payload = input.rest();
  std::vector<std::uint8_t> blob(payload.begin(), payload.end());
  if (mode & 0x80) {
    std::vector<std::uint8_t> z(ZSTD_compressBound(payload.size()));
    ZSTD_CCtx* c = ZSTD_createCCtx();
    ZSTD_CCtx_setParameter(c, ZSTD_c_checksumFlag, 1);
    const std::size_t n = ZSTD_compress2(c, z.data(), z.size(), payload.data(), payload.size());
    ZSTD_freeCCtx(c);
    if (ZSTD_isError(n)) return 0;
    z.resize(n);
    blob = std::move(z);
  }
  static recorder::Decoder decoder;  // one per thread, reused, as the reader does
  Image out;
  switch (mode % 3) {
    case 0:
      (void)decoder.decode_image(blob.data(), blob.size(), width, height, format, out);
      break;
    case 1:
      (void)decoder.decode_mask(blob.data(), blob.size(), width, height, out);
      break;
    default: {
      // The raw image a difference applies to was decoded already, so it has a sane size.
      const Image raw(1 + (width & 0xff), 1 + (height & 0xff), format);
      (void)decoder.decode_difference(blob.data(), blob.size(), box, raw, out);
      break;
    }
  }
  return 0;
}
