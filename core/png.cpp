#include "core/png.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>

#include <zlib.h>

namespace augrig {

struct PngEncoder::Stream {
  z_stream z{};
};

PngEncoder::PngEncoder(int compression, PngKind kind) : kind_(kind), z_(new Stream) {
  compression = std::clamp(compression, 0, 9);
  filter_ = compression == 0 ? 0 : kind == PngKind::kMask ? 2 : 1;
  const int strategy = compression != 1         ? Z_DEFAULT_STRATEGY
                       : kind == PngKind::kMask ? Z_RLE
                                                : Z_HUFFMAN_ONLY;
  // A band may refer back into the one before unless each starts a fresh stream; that matters
  // only where bands are swapped (images) and the coding has back-references (not Huffman-only,
  // not stored). Resetting costs a clear of the hash table per band.
  reset_each_band_ = kind == PngKind::kImage && compression >= 2;
  ok_ = deflateInit2(&z_->z, compression == 0 ? 0 : compression, Z_DEFLATED, -15, 8, strategy) == Z_OK;
}

PngEncoder::~PngEncoder() {
  if (ok_) deflateEnd(&z_->z);
  delete z_;
}

// Whether rows [y0, y1) of `image` equal `reuse_pixels`'s, so that the band's encoding can be reused.
bool PngEncoder::band_reusable(const Image& image, const Image& reuse_pixels, int y0, int y1) const {
  const std::size_t row_bytes =
      static_cast<std::size_t>(image.width()) * static_cast<std::size_t>(bytes_per_pixel(image.format()));
  for (int y = y0; y < y1; ++y)
    if (std::memcmp(image.row(y), reuse_pixels.row(y), row_bytes) != 0) return false;
  // Up reaches into the row above the band: that row must be the same too.
  if (filter_ == 2 && y0 > 0) return std::memcmp(image.row(y0 - 1), reuse_pixels.row(y0 - 1), row_bytes) == 0;
  return true;
}

// Rows [y0, y1) into filtered_, each with its filter byte first.
void PngEncoder::filter_band(const Image& image, int y0, int y1, std::size_t row_bytes, std::size_t bpp) {
  filtered_.resize(static_cast<std::size_t>(y1 - y0) * (row_bytes + 1));
  std::uint8_t* o = filtered_.data();
  for (int y = y0; y < y1; ++y) {
    const std::uint8_t* r = image.row(y);
    *o++ = static_cast<std::uint8_t>(filter_);
    if (filter_ == 1) {
      std::memcpy(o, r, bpp);
      for (std::size_t x = bpp; x < row_bytes; ++x) o[x] = static_cast<std::uint8_t>(r[x] - r[x - bpp]);
    } else if (filter_ == 2 && y > 0) {
      const std::uint8_t* u = image.row(y - 1);
      for (std::size_t x = 0; x < row_bytes; ++x) o[x] = static_cast<std::uint8_t>(r[x] - u[x]);
    } else {
      std::memcpy(o, r, row_bytes);
    }
    o += row_bytes;
  }
}

// filtered_ deflated into `band`, ending byte-aligned so that bands concatenate.
Status PngEncoder::deflate_band(PngBand& band, bool reset) {
  z_stream& z = z_->z;
  band.length = filtered_.size();
  band.adler = static_cast<std::uint32_t>(adler32(1L, filtered_.data(), static_cast<uInt>(filtered_.size())));
  if (reset && deflateReset(&z) != Z_OK) return make_error("zlib: deflateReset failed");
  band.bytes.resize(deflateBound(&z, static_cast<uLong>(filtered_.size())) + 64);
  z.next_in = filtered_.data();
  z.avail_in = static_cast<uInt>(filtered_.size());
  z.next_out = reinterpret_cast<Bytef*>(band.bytes.data());
  z.avail_out = static_cast<uInt>(band.bytes.size());
  const int rc = deflate(&z, Z_SYNC_FLUSH);
  if (rc != Z_OK || z.avail_in != 0) return make_error("zlib: deflate failed (", rc, ")");
  band.bytes.resize(band.bytes.size() - z.avail_out);
  return {};
}

Expected<PngImage> PngEncoder::encode(const Image& image, const PngImage* reuse, const Image* reuse_pixels) {
  if (!ok_) return make_error("zlib: deflateInit2 failed");
  PngImage out;
  out.width = image.width();
  out.height = image.height();
  out.channels = bytes_per_pixel(image.format());
  const std::size_t bpp = static_cast<std::size_t>(out.channels);
  const std::size_t row_bytes = static_cast<std::size_t>(out.width) * bpp;
  const int bands = (out.height + kPngBandRows - 1) / kPngBandRows;
  out.bands.resize(static_cast<std::size_t>(bands));
  const bool can_reuse = kind_ == PngKind::kImage && reuse && reuse_pixels && reuse->width == out.width &&
                         reuse->height == out.height && reuse->channels == out.channels &&
                         reuse->bands.size() == out.bands.size() && reuse_pixels->width() == out.width &&
                         reuse_pixels->height() == out.height;
  for (int b = 0; b < bands; ++b) {
    const int y0 = b * kPngBandRows, y1 = std::min(out.height, y0 + kPngBandRows);
    PngBand& band = out.bands[static_cast<std::size_t>(b)];
    if (can_reuse && band_reusable(image, *reuse_pixels, y0, y1)) {
      band = reuse->bands[static_cast<std::size_t>(b)];
      continue;
    }
    filter_band(image, y0, y1, row_bytes, bpp);
    if (Status s = deflate_band(band, b == 0 || reset_each_band_); !s) return s.error();
  }
  return out;
}

namespace {

void put_u32(std::string& s, std::uint32_t v) {
  const char b[4] = {static_cast<char>(v >> 24), static_cast<char>(v >> 16), static_cast<char>(v >> 8),
                     static_cast<char>(v)};
  s.append(b, 4);
}

void put_chunk(std::string& file, const char* type, const std::string& data) {
  put_u32(file, static_cast<std::uint32_t>(data.size()));
  const std::size_t start = file.size();
  file.append(type, 4);
  file += data;
  put_u32(file, static_cast<std::uint32_t>(crc32(0L, reinterpret_cast<const Bytef*>(file.data() + start),
                                                 static_cast<uInt>(file.size() - start))));
}

}  // namespace

std::string png_file(const PngImage& im) {
  std::string ihdr;
  put_u32(ihdr, static_cast<std::uint32_t>(im.width));
  put_u32(ihdr, static_cast<std::uint32_t>(im.height));
  const char colour = im.channels == 3 ? 2 : im.channels == 4 ? 6 : 0;
  ihdr += std::string{8, colour, 0, 0, 0};  // depth 8, colour type, deflate, adaptive filters, no interlace
  std::string idat = "\x78\x01";            // zlib header: deflate, 32 KiB window, fastest
  std::uint32_t adler = 1;
  for (const PngBand& b : im.bands) {
    idat += b.bytes;
    adler = static_cast<std::uint32_t>(adler32_combine(adler, b.adler, static_cast<z_off_t>(b.length)));
  }
  idat += std::string("\x03\x00", 2);  // final block, fixed Huffman codes, end of block at once
  put_u32(idat, adler);
  std::string file("\x89PNG\r\n\x1a\n", 8);
  file.reserve(idat.size() + 64);
  put_chunk(file, "IHDR", ihdr);
  put_chunk(file, "IDAT", idat);
  put_chunk(file, "IEND", {});
  return file;
}

Status write_binary_file(const std::string& path, const std::string& bytes) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return make_error(path, ": cannot create the file (", std::strerror(errno), ")");
  const bool ok = std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
  const int err = errno;
  if (std::fclose(f) != 0 || !ok)
    return make_error(path, ": cannot write the file (", std::strerror(ok ? errno : err), ")");
  return {};
}

}  // namespace augrig
