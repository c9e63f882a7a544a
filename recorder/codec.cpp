#include "recorder/codec.hpp"

#include <algorithm>
#include <cstring>
#include <string>

#include <zstd.h>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace augrig::recorder {

int predictor_distance(PixelFormat format) {
  if (is_bayer(format)) return 2;
  return bytes_per_pixel(format);
}

namespace {

std::size_t row_bytes(int width, PixelFormat f) {
  return static_cast<std::size_t>(width) * static_cast<std::size_t>(bytes_per_pixel(f));
}

// out[x] = in[x] - in[x - d] (mod 256); the first d bytes are copied.
void delta_row(const std::uint8_t* __restrict in, std::uint8_t* __restrict out, std::size_t n,
               std::size_t d) {
  std::size_t x = 0;
  for (; x < d && x < n; ++x) out[x] = in[x];
#if defined(__SSE2__)
  for (; x + 16 <= n; x += 16) {
    const __m128i a = _mm_loadu_si128(reinterpret_cast<const __m128i*>(in + x));
    const __m128i b = _mm_loadu_si128(reinterpret_cast<const __m128i*>(in + x - d));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + x), _mm_sub_epi8(a, b));
  }
#endif
  for (; x < n; ++x) out[x] = static_cast<std::uint8_t>(in[x] - in[x - d]);
}

#if defined(__SSE2__)
// The running sums of a row's residuals, 16 bytes at a time for d = 1, 2 and 4 (SSE2 only): the
// prefix sum with stride d inside the vector (log steps), plus the last d bytes of the previous
// vector broadcast in the same pattern. Only that broadcast is on the chain from vector to vector.
template <int D>
std::size_t undelta_sse2(std::uint8_t* p, std::size_t n) {
  if (n < 16 + D) return D;
  __m128i carry = _mm_setzero_si128();
  // The first D bytes are kept as they are: start at 0 with a zero carry (their sums are themselves).
  std::size_t x = 0;
  for (; x + 16 <= n; x += 16) {
    __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p + x));
    if constexpr (D == 1) v = _mm_add_epi8(v, _mm_slli_si128(v, 1));
    if constexpr (D <= 2) v = _mm_add_epi8(v, _mm_slli_si128(v, 2));
    v = _mm_add_epi8(v, _mm_slli_si128(v, 4));
    v = _mm_add_epi8(v, _mm_slli_si128(v, 8));
    v = _mm_add_epi8(v, carry);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(p + x), v);
    if constexpr (D == 1) {
      const __m128i b = _mm_unpackhi_epi8(v, v);  // byte 15 in word 7
      carry = _mm_shuffle_epi32(_mm_shufflehi_epi16(b, 0xFF), 0xFF);
    } else if constexpr (D == 2) {
      carry = _mm_shuffle_epi32(_mm_shufflehi_epi16(v, 0xFF), 0xFF);
    } else {
      carry = _mm_shuffle_epi32(v, 0xFF);
    }
  }
  return x;  // the scalar loop finishes the row from here
}
#endif

// The inverse of delta_row, in place.
void undelta_row(std::uint8_t* p, std::size_t n, std::size_t d) {
  std::size_t x = d;
#if defined(__SSE2__)
  if (d == 1) x = std::max(x, undelta_sse2<1>(p, n));
  if (d == 2) x = std::max(x, undelta_sse2<2>(p, n));
  if (d == 4) x = std::max(x, undelta_sse2<4>(p, n));
#endif
  for (; x < n; ++x) p[x] = static_cast<std::uint8_t>(p[x] + p[x - d]);
}

void xor_bytes(const std::uint8_t* __restrict a, const std::uint8_t* __restrict b,
               std::uint8_t* __restrict out, std::size_t n) {
  std::size_t x = 0;
#if defined(__SSE2__)
  for (; x + 16 <= n; x += 16) {
    const __m128i va = _mm_loadu_si128(reinterpret_cast<const __m128i*>(a + x));
    const __m128i vb = _mm_loadu_si128(reinterpret_cast<const __m128i*>(b + x));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + x), _mm_xor_si128(va, vb));
  }
#endif
  for (; x < n; ++x) out[x] = a[x] ^ b[x];
}

std::uint64_t load64(const std::uint8_t* p) {
  std::uint64_t v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

// Index of the first byte in [0, limit) where a and b differ, or `limit`; eight bytes at a time.
std::size_t first_difference(const std::uint8_t* a, const std::uint8_t* b, std::size_t limit) {
  std::size_t i = 0;
  while (i + 8 <= limit && load64(a + i) == load64(b + i)) i += 8;
  while (i < limit && a[i] == b[i]) ++i;
  return i;
}

// One past the last byte in [floor, n) where a and b differ, or `floor`.
std::size_t last_difference(const std::uint8_t* a, const std::uint8_t* b, std::size_t n, std::size_t floor) {
  std::size_t e = n;
  while (e >= floor + 8 && load64(a + e - 8) == load64(b + e - 8)) e -= 8;
  while (e > floor && a[e - 1] == b[e - 1]) --e;
  return e;
}

Error zstd_error(const char* what, std::size_t code) {
  return make_error("zstd ", what, ": ", ZSTD_getErrorName(code));
}

}  // namespace

ChangedBox changed_box(ConstImageView a, ConstImageView b) {
  ChangedBox box;
  const std::size_t n = row_bytes(a.width, a.format);
  const std::size_t bpp = static_cast<std::size_t>(bytes_per_pixel(a.format));
  std::size_t lo = n, hi = 0;  // byte range [lo, hi) that differs in some row
  int y0 = -1, y1 = -1;
  for (int y = 0; y < a.height; ++y) {
    const std::uint8_t* ra = a.row(y);
    const std::uint8_t* rb = b.row(y);
    if (std::memcmp(ra, rb, n) == 0) continue;
    if (y0 < 0) y0 = y;
    y1 = y + 1;
    lo = std::min(lo, first_difference(ra, rb, lo));
    hi = std::max(hi, last_difference(ra, rb, n, hi));
  }
  if (y0 < 0) return box;
  box.x0 = static_cast<int>(lo / bpp);
  box.x1 = static_cast<int>((hi + bpp - 1) / bpp);
  box.y0 = y0;
  box.y1 = y1;
  return box;
}

std::uint64_t raw_fingerprint(ConstImageView image) {
  constexpr std::uint64_t kMul = 0x9E3779B97F4A7C15ull;
  auto mix = [](std::uint64_t h, std::uint64_t v) {
    h ^= v + (h << 6) + (h >> 2);
    return h * kMul;
  };
  std::uint64_t h = mix(mix(mix(0x243F6A8885A308D3ull, static_cast<std::uint64_t>(image.width)),
                            static_cast<std::uint64_t>(image.height)),
                        static_cast<std::uint64_t>(image.format));
  if (image.empty()) return h;
  const std::size_t n = row_bytes(image.width, image.format);
  for (int y = 0; y < image.height; y += 8) {
    const std::uint8_t* r = image.row(y);
    // Four independent lanes: the multiply's latency, not the bytes, bounds a single chain.
    std::uint64_t a = h, b = h ^ 1, c = h ^ 2, d = h ^ 3;
    std::size_t x = 0;
    for (; x + 32 <= n; x += 32) {
      a = mix(a, load64(r + x));
      b = mix(b, load64(r + x + 8));
      c = mix(c, load64(r + x + 16));
      d = mix(d, load64(r + x + 24));
    }
    std::uint64_t tail = 0;
    for (; x < n; ++x) tail = mix(tail, r[x]);
    h = mix(mix(mix(mix(mix(h, a), b), c), d), tail);
  }
  return h;
}

Encoder::Encoder(int zstd_level) : cctx_(ZSTD_createCCtx()) {
  ZSTD_CCtx_setParameter(cctx_, ZSTD_c_compressionLevel, zstd_level);
  ZSTD_CCtx_setParameter(cctx_, ZSTD_c_checksumFlag, 1);
  ZSTD_CCtx_setParameter(cctx_, ZSTD_c_contentSizeFlag, 1);
}

Encoder::~Encoder() {
  ZSTD_freeCCtx(cctx_);
}

Status Encoder::compress(const std::uint8_t* src, std::size_t n, std::vector<std::uint8_t>& out) {
  if (!cctx_) return make_error("zstd: could not create a compression context");
  // Into a buffer kept between calls, then the r compressed bytes copied out: growing a fresh
  // `out` to zstd's bound zeroed 1.2 MB per 1280x960 image first (1.4 % of a live run's CPU, perf).
  const std::size_t bound = ZSTD_compressBound(n);
  if (compressed_.size() < bound) compressed_.resize(bound);
  const std::size_t r = ZSTD_compress2(cctx_, compressed_.data(), compressed_.size(), src, n);
  if (ZSTD_isError(r)) {
    out.clear();
    return zstd_error("compress", r);
  }
  out.assign(compressed_.data(), compressed_.data() + r);
  return {};
}

Status Encoder::encode_image(ConstImageView image, std::vector<std::uint8_t>& out) {
  if (image.empty()) return make_error("empty image");
  const std::size_t n = row_bytes(image.width, image.format);
  const std::size_t d = static_cast<std::size_t>(predictor_distance(image.format));
  scratch_.resize(n * static_cast<std::size_t>(image.height));
  for (int y = 0; y < image.height; ++y) delta_row(image.row(y), scratch_.data() + n * y, n, d);
  return compress(scratch_.data(), scratch_.size(), out);
}

Status Encoder::encode_mask(ConstImageView mask, std::vector<std::uint8_t>& out) {
  if (mask.empty()) return make_error("empty mask");
  if (mask.format != PixelFormat::kMono8)
    return make_error("mask is ", to_string(mask.format), ", expected Mono8");
  const std::size_t n = static_cast<std::size_t>(mask.width);
  if (mask.stride_bytes == n) return compress(mask.data, n * static_cast<std::size_t>(mask.height), out);
  scratch_.resize(n * static_cast<std::size_t>(mask.height));
  for (int y = 0; y < mask.height; ++y) std::memcpy(scratch_.data() + n * y, mask.row(y), n);
  return compress(scratch_.data(), scratch_.size(), out);
}

Status Encoder::encode_difference(ConstImageView raw, ConstImageView augmented, ChangedBox& box,
                                  std::vector<std::uint8_t>& out) {
  if (raw.width != augmented.width || raw.height != augmented.height || raw.format != augmented.format)
    return make_error("augmented image ", augmented.width, "x", augmented.height, " ",
                      to_string(augmented.format), " differs from the raw image ", raw.width, "x", raw.height,
                      " ", to_string(raw.format));
  // The whole image is its part inside the whole image's box: one path for both forms.
  return encode_difference(raw, augmented, PixelBox{0, 0, raw.width, raw.height}, box, out);
}

Status Encoder::encode_difference(ConstImageView raw, ConstImageView part, const PixelBox& within,
                                  ChangedBox& box, std::vector<std::uint8_t>& out) {
  if (!within.empty() && part.format != raw.format)
    return make_error("augmented image's part is ", to_string(part.format), ", the raw image ",
                      to_string(raw.format));
  if (!within.inside(raw.width, raw.height))
    return make_error("augmented box [", within.x0, ", ", within.x1, ") x [", within.y0, ", ", within.y1,
                      ") is not inside the raw image ", raw.width, "x", raw.height);
  if (part.width != within.width() || part.height != within.height())
    return make_error("augmented image's part ", part.width, "x", part.height,
                      " differs from its box's size ", within.width(), "x", within.height());
  out.clear();
  box = {};
  if (within.empty()) return {};
  const ChangedBox b = changed_box(sub_view(raw, within), part);  // in the part's pixels
  if (b.empty()) return {};
  box = {b.x0 + within.x0, b.y0 + within.y0, b.x1 + within.x0, b.y1 + within.y0};
  // raw XOR augmented inside the box, rows packed tight.
  const ConstImageView r = sub_view(raw, box), a = sub_view(part, b);
  const std::size_t n = row_bytes(r.width, r.format);
  scratch_.resize(n * static_cast<std::size_t>(r.height));
  for (int y = 0; y < r.height; ++y) xor_bytes(r.row(y), a.row(y), scratch_.data() + n * y, n);
  return compress(scratch_.data(), scratch_.size(), out);
}

Status Encoder::encode_depth(const float* values, int width, int height, std::vector<std::uint8_t>& out) {
  out.clear();
  if (width <= 0 || height <= 0) return {};
  const std::size_t w = static_cast<std::size_t>(width), n = w * static_cast<std::size_t>(height);
  scratch_.resize(4 * n);
  std::uint8_t* planes = scratch_.data();
  for (std::size_t y = 0; y < static_cast<std::size_t>(height); ++y) {
    std::uint32_t prev = 0;
    for (std::size_t x = 0; x < w; ++x) {
      const std::size_t i = y * w + x;
      std::uint32_t b;
      std::memcpy(&b, values + i, sizeof b);
      // Neighbouring depths on one surface differ in their low mantissa bits only.
      const std::uint32_t r = b - prev;
      prev = b;
      for (std::size_t k = 0; k < 4; ++k) planes[k * n + i] = static_cast<std::uint8_t>(r >> (8 * k));
    }
  }
  return compress(planes, 4 * n, out);
}

Decoder::Decoder() : dctx_(ZSTD_createDCtx()) {}

Decoder::~Decoder() {
  ZSTD_freeDCtx(dctx_);
}

namespace {

// The largest image side a recording may hold. No camera comes near it, and the largest image it
// allows (65535^2 RGBA8, 17 GB) still fits in size_t; a damaged or hostile row's size beyond it is
// refused before anything is allocated.
constexpr int kMaxImageSide = 65535;

// The zstd frame's header against the bytes expected, before any memory is allocated for them:
// a row's width and height say what to allocate, and only the frame's declared content size
// says whether the blob can fill it.
Status check_frame(const std::uint8_t* blob, std::size_t n, std::size_t expected) {
  if (blob == nullptr || n == 0)
    return make_error("empty blob, expected a zstd frame of ", expected, " bytes");
  const unsigned long long size = ZSTD_getFrameContentSize(blob, n);
  if (size == ZSTD_CONTENTSIZE_ERROR) return make_error("not a zstd frame (", n, " bytes)");
  if (size == ZSTD_CONTENTSIZE_UNKNOWN) return make_error("zstd frame without content size");
  if (size != expected)
    return make_error("zstd frame holds ", std::to_string(size), " bytes, expected ", expected);
  return {};
}

// The bytes of a width x height image of `format`, rows packed tight, when the size is sane.
Expected<std::size_t> image_bytes(const char* what, int width, int height, PixelFormat format) {
  if (width <= 0 || height <= 0 || width > kMaxImageSide || height > kMaxImageSide)
    return make_error("bad ", what, " size ", width, "x", height, " (each side 1..", kMaxImageSide, ")");
  return row_bytes(width, format) * static_cast<std::size_t>(height);
}

// check_frame() with the image's size in the message.
Status check_image_frame(const char* what, const std::uint8_t* blob, std::size_t n, int width, int height,
                         PixelFormat format, std::size_t expected) {
  if (auto st = check_frame(blob, n, expected); !st)
    return make_error(st.error().message, " (a ", width, "x", height, " ", to_string(format), " ", what, ")");
  return {};
}

}  // namespace

Status Decoder::decompress(const std::uint8_t* blob, std::size_t n, std::uint8_t* dst, std::size_t expected) {
  if (!dctx_) return make_error("zstd: could not create a decompression context");
  if (auto st = check_frame(blob, n, expected); !st) return st;
  const std::size_t frame = ZSTD_findFrameCompressedSize(blob, n);
  if (ZSTD_isError(frame)) return zstd_error("frame", frame);
  if (frame != n) return make_error("blob has ", n - frame, " bytes after its zstd frame");
  const std::size_t r = ZSTD_decompressDCtx(dctx_, dst, expected, blob, n);
  if (ZSTD_isError(r)) return zstd_error("decompress", r);
  if (r != expected) return make_error("zstd frame decompressed to ", r, " bytes, expected ", expected);
  return {};
}

Status Decoder::decode_image(const std::uint8_t* blob, std::size_t n, int width, int height,
                             PixelFormat format, Image& out) {
  const auto bytes = image_bytes("image", width, height, format);
  if (!bytes) return bytes.error();
  if (auto st = check_image_frame("image", blob, n, width, height, format, *bytes); !st) return st;
  const std::size_t rb = row_bytes(width, format);
  if (out.width() != width || out.height() != height || out.format() != format || out.stride_bytes() != rb)
    out = Image(width, height, format);
  if (auto st = decompress(blob, n, out.data(), *bytes); !st) return st;
  const std::size_t d = static_cast<std::size_t>(predictor_distance(format));
  for (int y = 0; y < height; ++y) undelta_row(out.row(y), rb, d);
  return {};
}

Status Decoder::decode_mask(const std::uint8_t* blob, std::size_t n, int width, int height, Image& out) {
  const auto bytes = image_bytes("mask", width, height, PixelFormat::kMono8);
  if (!bytes) return bytes.error();
  if (auto st = check_image_frame("mask", blob, n, width, height, PixelFormat::kMono8, *bytes); !st)
    return st;
  const std::size_t rb = static_cast<std::size_t>(width);
  if (out.width() != width || out.height() != height || out.format() != PixelFormat::kMono8 ||
      out.stride_bytes() != rb)
    out = Image(width, height, PixelFormat::kMono8);
  return decompress(blob, n, out.data(), *bytes);
}

Status Decoder::decode_difference(const std::uint8_t* blob, std::size_t n, const ChangedBox& box,
                                  const Image& raw, Image& out) {
  out = Image::copy_of(raw.view());
  if (box.empty()) {
    if (n != 0) return make_error("empty change box but a ", n, "-byte blob");
    return {};
  }
  if (box.x0 < 0 || box.y0 < 0 || box.x1 > raw.width() || box.y1 > raw.height())
    return make_error("change box [", box.x0, ", ", box.x1, ") x [", box.y0, ", ", box.y1, ") outside the ",
                      raw.width(), "x", raw.height(), " image");
  const std::size_t bpp = static_cast<std::size_t>(bytes_per_pixel(raw.format()));
  const std::size_t off = static_cast<std::size_t>(box.x0) * bpp;
  const std::size_t rb = static_cast<std::size_t>(box.x1 - box.x0) * bpp;
  scratch_.resize(rb * static_cast<std::size_t>(box.y1 - box.y0));
  if (auto st = decompress(blob, n, scratch_.data(), scratch_.size()); !st) return st;
  for (int y = box.y0; y < box.y1; ++y)
    xor_bytes(raw.row(y) + off, scratch_.data() + rb * (y - box.y0), out.row(y) + off, rb);
  return {};
}

Status Decoder::decode_depth(const std::uint8_t* blob, std::size_t n, int width, int height,
                             std::vector<float>& out) {
  out.clear();
  if (width == 0 && height == 0) {
    if (n != 0) return make_error("empty depth box but a ", n, "-byte blob");
    return {};
  }
  const auto bytes = image_bytes("depth box", width, height, PixelFormat::kRGBA8);  // 4 bytes a value
  if (!bytes) return bytes.error();
  if (auto st = check_frame(blob, n, *bytes); !st)
    return make_error(st.error().message, " (a ", width, "x", height, " float32 depth box)");
  scratch_.resize(*bytes);
  if (auto st = decompress(blob, n, scratch_.data(), scratch_.size()); !st) return st;
  const std::size_t w = static_cast<std::size_t>(width), count = w * static_cast<std::size_t>(height);
  out.resize(count);
  const std::uint8_t* planes = scratch_.data();
  for (std::size_t y = 0; y < static_cast<std::size_t>(height); ++y) {
    std::uint32_t b = 0;
    for (std::size_t x = 0; x < w; ++x) {
      const std::size_t i = y * w + x;
      const std::uint32_t r = static_cast<std::uint32_t>(planes[i]) |
                              static_cast<std::uint32_t>(planes[count + i]) << 8 |
                              static_cast<std::uint32_t>(planes[2 * count + i]) << 16 |
                              static_cast<std::uint32_t>(planes[3 * count + i]) << 24;
      b += r;
      std::memcpy(&out[i], &b, sizeof b);
    }
  }
  return {};
}

}  // namespace augrig::recorder
