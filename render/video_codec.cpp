// H264Encoder and H264Decoder (video_codec.hpp) over FFmpeg's libavcodec and libswscale.
extern "C" {
#include <libavcodec/avcodec.h>
#include <libavutil/opt.h>
#include <libswscale/swscale.h>
}

#include <algorithm>
#include <cstring>
#include <mutex>

#include <opencv2/core.hpp>

#include "render/cv_image.hpp"
#include "render/video_codec.hpp"

namespace augrig {

namespace {

std::string av_error(int code) {
  char buf[AV_ERROR_MAX_STRING_SIZE] = {};
  av_strerror(code, buf, sizeof buf);
  return buf;
}

// swscale's colour details: `yuv_is_709` picks the matrix of the YUV side, RGB and gray full range.
void set_colour(SwsContext* sws, bool to_yuv, bool yuv_is_709, bool yuv_full_range) {
  const int* yuv = sws_getCoefficients(yuv_is_709 ? SWS_CS_ITU709 : SWS_CS_DEFAULT);
  const int* rgb = sws_getCoefficients(SWS_CS_DEFAULT);
  if (to_yuv)
    sws_setColorspaceDetails(sws, rgb, 1, yuv, yuv_full_range ? 1 : 0, 0, 1 << 16, 1 << 16);
  else
    sws_setColorspaceDetails(sws, yuv, yuv_full_range ? 1 : 0, rgb, 1, 0, 1 << 16, 1 << 16);
}

// Gray as limited-range luma with neutral chroma, exactly 128 (the decoder knows gray by it).
void gray_to_yuv(const cv::Mat& gray, AVFrame& f) {
  std::uint8_t lut[256];
  for (int v = 0; v < 256; ++v) lut[v] = static_cast<std::uint8_t>(16 + (v * 219 + 127) / 255);
  for (int y = 0; y < f.height; ++y) {
    const std::uint8_t* s = gray.ptr<std::uint8_t>(y);
    std::uint8_t* d = f.data[0] + static_cast<std::ptrdiff_t>(y) * f.linesize[0];
    for (int x = 0; x < f.width; ++x) d[x] = lut[s[x]];
  }
  for (int p = 1; p <= 2; ++p)
    for (int y = 0; y < (f.height + 1) / 2; ++y)
      std::memset(f.data[p] + static_cast<std::ptrdiff_t>(y) * f.linesize[p], 128,
                  static_cast<std::size_t>((f.width + 1) / 2));
}

// Limited-range luma back to full-range gray.
void yuv_to_gray(const AVFrame& f, bool full_range, Image& out) {
  std::uint8_t lut[256];
  for (int v = 0; v < 256; ++v)
    lut[v] = full_range ? static_cast<std::uint8_t>(v)
                        : static_cast<std::uint8_t>(std::clamp(((v - 16) * 255 + 109) / 219, 0, 255));
  for (int y = 0; y < out.height(); ++y) {
    const std::uint8_t* s = f.data[0] + static_cast<std::ptrdiff_t>(y) * f.linesize[0];
    std::uint8_t* d = out.row(y);
    for (int x = 0; x < out.width(); ++x) d[x] = lut[s[x]];
  }
}

// FFmpeg speaks at info level on every encoder's close (x264's statistics): errors only.
void quiet_ffmpeg() {
  static std::once_flag once;
  std::call_once(once, [] { av_log_set_level(AV_LOG_ERROR); });
}

constexpr const char* kPresets[] = {"ultrafast", "superfast", "veryfast", "faster",  "fast",
                                    "medium",    "slow",      "slower",   "veryslow"};

}  // namespace

bool is_x264_preset(const std::string& name) {
  return std::find(std::begin(kPresets), std::end(kPresets), name) != std::end(kPresets);
}

std::string x264_preset_names() {
  std::string s;
  for (const char* p : kPresets) s += (s.empty() ? "" : ", ") + std::string(p);
  return s;
}

// ---- The encoder --------------------------------------------------------------------------------

struct H264Encoder::Impl {
  AVCodecContext* codec = nullptr;
  AVFrame* frame = nullptr;
  AVPacket* packet = nullptr;
  SwsContext* sws = nullptr;
  std::int64_t last_pts = -1;

  ~Impl() {
    sws_freeContext(sws);
    av_packet_free(&packet);
    av_frame_free(&frame);
    avcodec_free_context(&codec);
  }

  // Colour (RGB24, RGBA or BGR24) into the frame's 4:2:0 planes, BT.709 limited range.
  Status rgb_to_yuv(const cv::Mat& src, AVPixelFormat fmt) {
    const int w = frame->width, h = frame->height;
    sws = sws_getCachedContext(sws, w, h, fmt, w, h, AV_PIX_FMT_YUV420P, SWS_BILINEAR, nullptr, nullptr,
                               nullptr);
    if (!sws) return make_error("H264Encoder::encode(): no conversion to YUV 4:2:0");
    set_colour(sws, true, true, false);
    const std::uint8_t* planes[1] = {src.data};
    const int strides[1] = {static_cast<int>(src.step[0])};
    sws_scale(sws, planes, strides, 0, h, frame->data, frame->linesize);
    return {};
  }
};

Expected<std::unique_ptr<H264Encoder>> H264Encoder::create(int width_px, int height_px,
                                                           const H264Options& o) {
  const std::string where = "H264Encoder::create(): ";
  if (width_px < 2 || height_px < 2 || width_px > 16384 || height_px > 16384)
    return make_error(where, width_px, "x", height_px, " pixels: expected 2x2 to 16384x16384");
  if (o.gop_frames < 1)
    return make_error(where, "keyframe interval ", o.gop_frames, ": expected at least 1 frame");
  if (o.crf < 0 || o.crf > 51) return make_error(where, "crf ", o.crf, ": expected 0..51");
  if (o.max_kbps < 0)
    return make_error(where, "bit-rate cap ", o.max_kbps, " kbit/s: expected 0 (none) or more");
  if (o.threads < 1 || o.threads > 16) return make_error(where, o.threads, " threads: expected 1..16");
  if (!is_x264_preset(o.preset))
    return make_error(where, "preset '", o.preset, "': expected one of ", x264_preset_names());
  quiet_ffmpeg();
  const AVCodec* codec = avcodec_find_encoder_by_name("libx264");
  if (!codec)
    return make_error(where, "this FFmpeg has no libx264 encoder (Debian: libavcodec59 with libx264)");

  std::unique_ptr<H264Encoder> e(new H264Encoder());
  e->impl_ = std::make_unique<Impl>();
  e->width_ = width_px;
  e->height_ = height_px;
  Impl& im = *e->impl_;
  im.codec = avcodec_alloc_context3(codec);
  AVCodecContext* c = im.codec;
  c->width = (width_px + 1) / 2 * 2;
  c->height = (height_px + 1) / 2 * 2;
  c->pix_fmt = AV_PIX_FMT_YUV420P;
  c->time_base = {1, 1'000'000};  // microseconds: frames come at any pace
  c->framerate = {30, 1};         // rate control's guess of the pace
  c->gop_size = o.gop_frames;
  c->keyint_min = 1;
  c->max_b_frames = 0;
  c->thread_count = o.threads;
  c->colorspace = AVCOL_SPC_BT709;
  c->color_primaries = AVCOL_PRI_BT709;
  c->color_trc = AVCOL_TRC_IEC61966_2_1;  // the cameras' 8-bit values are sRGB-like
  c->color_range = AVCOL_RANGE_MPEG;
  if (o.max_kbps > 0) {
    c->rc_max_rate = std::int64_t{o.max_kbps} * 1000;
    c->rc_buffer_size = o.max_kbps * 1000;
  }
  // No GLOBAL_HEADER flag: x264 then repeats SPS and PPS before every IDR, as a joining client needs.
  av_opt_set(c->priv_data, "preset", o.preset.c_str(), 0);
  av_opt_set(c->priv_data, "tune", "zerolatency",
             0);  // no lookahead, no frame threads: a unit per frame at once
  av_opt_set_int(c->priv_data, "crf", o.crf, 0);
  av_opt_set_int(c->priv_data, "forced-idr", 1, 0);  // a keyframe asked for is an IDR
  if (int r = avcodec_open2(c, codec, nullptr); r < 0)
    return make_error(where, "cannot open x264 (preset '", o.preset, "'): ", av_error(r));
  im.frame = av_frame_alloc();
  im.frame->format = AV_PIX_FMT_YUV420P;
  im.frame->width = c->width;
  im.frame->height = c->height;
  if (int r = av_frame_get_buffer(im.frame, 0); r < 0)
    return make_error(where, "frame buffer: ", av_error(r));
  im.packet = av_packet_alloc();
  return e;
}

H264Encoder::~H264Encoder() = default;

Expected<H264AccessUnit> H264Encoder::encode(ConstImageView image, TimestampNs t_ns, bool keyframe) {
  const char* where = "H264Encoder::encode(): ";
  if (image.width != width_ || image.height != height_)
    return make_error(where, "a ", image.width, "x", image.height, " image, the encoder's size is ", width_,
                      "x", height_);
  Impl& im = *impl_;
  // The pixels as swscale takes them: Bayer demosaiced, odd sizes padded to the coded size.
  cv::Mat src = is_bayer(image.format) ? bgr_of(image) : cv_view(image);
  AVPixelFormat src_fmt = AV_PIX_FMT_GRAY8;
  if (is_bayer(image.format))
    src_fmt = AV_PIX_FMT_BGR24;
  else if (image.format == PixelFormat::kRGB8)
    src_fmt = AV_PIX_FMT_RGB24;
  else if (image.format == PixelFormat::kRGBA8)
    src_fmt = AV_PIX_FMT_RGBA;
  else if (image.format != PixelFormat::kMono8)
    return make_error(where, "pixel format ", to_string(image.format), " is not one it codes");
  const int cw = im.codec->width, ch = im.codec->height;
  if (cw != width_ || ch != height_)
    cv::copyMakeBorder(src, src, 0, ch - height_, 0, cw - width_, cv::BORDER_REPLICATE);
  if (int r = av_frame_make_writable(im.frame); r < 0)
    return make_error(where, "frame buffer: ", av_error(r));
  if (src_fmt == AV_PIX_FMT_GRAY8)
    gray_to_yuv(src, *im.frame);
  else if (Status st = im.rgb_to_yuv(src, src_fmt); !st)
    return st.error();

  // Time in microseconds, never backwards (x264 wants increasing times).
  std::int64_t pts = t_ns / 1000;
  if (pts <= im.last_pts) pts = im.last_pts + 1;
  im.frame->pts = im.last_pts = pts;
  im.frame->pict_type = keyframe ? AV_PICTURE_TYPE_I : AV_PICTURE_TYPE_NONE;
  if (int r = avcodec_send_frame(im.codec, im.frame); r < 0) return make_error(where, "x264: ", av_error(r));
  H264AccessUnit unit;
  for (;;) {
    const int r = avcodec_receive_packet(im.codec, im.packet);
    if (r == AVERROR(EAGAIN) || r == AVERROR_EOF) break;
    if (r < 0) return make_error(where, "x264: ", av_error(r));
    unit.data.insert(unit.data.end(), im.packet->data, im.packet->data + im.packet->size);
    unit.keyframe = unit.keyframe || (im.packet->flags & AV_PKT_FLAG_KEY);
    av_packet_unref(im.packet);
  }
  // zerolatency gives each frame's unit at once; one held back would make every unit a frame late.
  if (unit.data.empty()) return make_error(where, "x264 gave no unit for frame ", frames_, " (held back)");
  ++frames_;
  return unit;
}

// ---- The decoder --------------------------------------------------------------------------------

struct H264Decoder::Impl {
  AVCodecContext* codec = nullptr;
  AVFrame* frame = nullptr;
  AVPacket* packet = nullptr;
  SwsContext* sws = nullptr;
  std::uint64_t pictures = 0;  // decoded so far

  ~Impl() {
    sws_freeContext(sws);
    av_packet_free(&packet);
    av_frame_free(&frame);
    avcodec_free_context(&codec);
  }
};

Expected<std::unique_ptr<H264Decoder>> H264Decoder::create() {
  quiet_ffmpeg();
  const AVCodec* codec = avcodec_find_decoder(AV_CODEC_ID_H264);
  if (!codec) return make_error("H264Decoder::create(): this FFmpeg has no H.264 decoder");
  std::unique_ptr<H264Decoder> d(new H264Decoder());
  d->impl_ = std::make_unique<Impl>();
  Impl& im = *d->impl_;
  im.codec = avcodec_alloc_context3(codec);
  im.codec->thread_count = 1;  // frame threads would give each picture threads-1 units late
  im.codec->flags |= AV_CODEC_FLAG_LOW_DELAY;
  if (int r = avcodec_open2(im.codec, codec, nullptr); r < 0)
    return make_error("H264Decoder::create(): ", av_error(r));
  im.frame = av_frame_alloc();
  im.packet = av_packet_alloc();
  return d;
}

H264Decoder::~H264Decoder() = default;

namespace {

// Whether both chroma planes of a 4:2:0 picture are 128 throughout (coded gray).
bool neutral_chroma(const AVFrame& f) {
  const int cw = (f.width + 1) / 2, ch = (f.height + 1) / 2;
  for (int p = 1; p <= 2; ++p)
    for (int y = 0; y < ch; ++y) {
      const std::uint8_t* row = f.data[p] + static_cast<std::ptrdiff_t>(y) * f.linesize[p];
      if (std::any_of(row, row + cw, [](std::uint8_t v) { return v != 128; })) return false;
    }
  return true;
}

}  // namespace

Expected<Image> H264Decoder::decode(const std::uint8_t* data, std::size_t size, int width_px, int height_px) {
  const char* where = "H264Decoder::decode(): ";
  if (!data || size == 0) return make_error(where, "an empty access unit");
  if (size > (std::size_t{1} << 30)) return make_error(where, "an access unit of ", size, " bytes");
  Impl& im = *impl_;
  if (int r = av_new_packet(im.packet, static_cast<int>(size)); r < 0) return make_error(where, av_error(r));
  std::memcpy(im.packet->data, data, size);
  const int sent = avcodec_send_packet(im.codec, im.packet);
  av_packet_unref(im.packet);
  const int r = sent < 0 ? sent : avcodec_receive_frame(im.codec, im.frame);
  // Before the first picture, what fails is a stream joined between keyframes.
  if (r < 0 && im.pictures == 0)
    return make_error(where, "no picture yet: the stream must begin at a keyframe (", av_error(r), ")");
  if (r == AVERROR(EAGAIN)) return make_error(where, "no picture from this unit");
  if (r < 0) return make_error(where, "damaged data: ", av_error(r));
  std::unique_ptr<AVFrame, void (*)(AVFrame*)> held(im.frame, av_frame_unref);
  const AVFrame& f = *im.frame;
  if (f.format != AV_PIX_FMT_YUV420P && f.format != AV_PIX_FMT_YUVJ420P)
    return make_error(where, "a picture in pixel format ", f.format, " (expected 4:2:0, 8 bits)");
  ++im.pictures;
  const int w = width_px > 0 ? std::min(width_px, f.width) : f.width;
  const int h = height_px > 0 ? std::min(height_px, f.height) : f.height;
  const bool full_range = f.color_range == AVCOL_RANGE_JPEG || f.format == AV_PIX_FMT_YUVJ420P;
  if (neutral_chroma(f)) {
    Image gray(w, h, PixelFormat::kMono8);
    yuv_to_gray(f, full_range, gray);
    return gray;
  }
  Image out(w, h, PixelFormat::kRGB8);
  im.sws = sws_getCachedContext(im.sws, w, h, static_cast<AVPixelFormat>(f.format), w, h, AV_PIX_FMT_RGB24,
                                SWS_BILINEAR, nullptr, nullptr, nullptr);
  if (!im.sws) return make_error(where, "no conversion from YUV 4:2:0");
  set_colour(im.sws, false, f.colorspace == AVCOL_SPC_BT709, full_range);
  std::uint8_t* dst[1] = {out.data()};
  const int dst_stride[1] = {static_cast<int>(out.stride_bytes())};
  sws_scale(im.sws, f.data, f.linesize, 0, h, dst, dst_stride);
  return out;
}

}  // namespace augrig
