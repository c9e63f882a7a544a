// A video file as a sink: both augmented views side by side (optionally their masks' colours
// blended over them, render/visualize.hpp), H.264 through FFmpeg's libavcodec (x264) in the
// container the file's extension names (.mp4, .mkv, ...), readable by ffprobe, ffmpeg and any
// player. Each pair's presentation time is its key time from the first pair's on a 90 kHz clock,
// so the video runs at the source's own rate, gaps and all; no B-frames (a frame is final when
// encoded), a keyframe every two seconds of a 30 fps stream. Options after the file name:
// `masks` (the mask colours, docs/STATISTICS.md's), `crf=N` (x264's quality, 0..51, default 23).
// Encoding runs on the pipeline's thread (a file job waits for it rather than lose pairs); x264
// uses its own threads. Errors name the file and what FFmpeg said.
extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/opt.h>
#include <libswscale/swscale.h>
}

#include <algorithm>
#include <cstring>
#include <sstream>

#include "pipeline/sinks/registry.hpp"
#include "render/visualize.hpp"

namespace augrig::pipeline {

namespace {

constexpr AVRational kTimeBase{1, 90'000};

std::string av_error(int code) {
  char buf[AV_ERROR_MAX_STRING_SIZE] = {};
  av_strerror(code, buf, sizeof buf);
  return buf;
}

struct VideoOptions {
  std::string path;
  bool masks = false;
  int crf = 23;
};

Expected<VideoOptions> parse_options(const std::string& arg) {
  VideoOptions o;
  std::istringstream in(arg);
  std::getline(in, o.path, ',');
  for (std::string opt; std::getline(in, opt, ',');) {
    if (opt == "masks") {
      o.masks = true;
    } else if (opt.rfind("crf=", 0) == 0) {
      char* end = nullptr;
      const long crf = std::strtol(opt.c_str() + 4, &end, 10);
      if (*end || end == opt.c_str() + 4 || crf < 0 || crf > 51)
        return make_error("video sink: ", opt, ": expected crf=N with N a whole number 0..51");
      o.crf = static_cast<int>(crf);
    } else {
      return make_error("video sink: ", opt, ": unknown option (expected masks or crf=N)");
    }
  }
  if (o.path.empty()) return make_error("video sink: expected a file name (video:FILE.mp4)");
  return o;
}

class VideoSink final : public FrameSink {
 public:
  explicit VideoSink(VideoOptions o) : o_(std::move(o)) {}
  ~VideoSink() override { release_all(); }
  VideoSink(const VideoSink&) = delete;
  VideoSink& operator=(const VideoSink&) = delete;

  Status open(const Rig& rig);
  SinkNeeds needs() const override { return {.whole_images = true}; }
  Status consume(PairContext& pair) override;
  Status close(PipelineReport& report) override;

 private:
  Status fail(const char* what, int code) {
    return make_error("video sink: ", o_.path, ": ", what, ": ", av_error(code));
  }
  Status compose(PairContext& pair);
  Status encode(AVFrame* frame);  // null: flush
  void release_all();

  VideoOptions o_;
  int view_w_[2] = {0, 0}, width_ = 0, height_ = 0;
  AVFormatContext* fmt_ = nullptr;
  AVCodecContext* codec_ = nullptr;
  AVStream* stream_ = nullptr;
  AVFrame* frame_ = nullptr;
  AVPacket* packet_ = nullptr;
  SwsContext* sws_ = nullptr;
  Image canvas_;  // RGB8, both views side by side
  std::optional<TimestampNs> first_t_ns_;
  std::int64_t last_pts_ = -1;
  std::int64_t interval_ = kTimeBase.den / 30;  // the last pair's interval, in kTimeBase
  bool header_written_ = false, closed_ = false;
};

// The encoder and the file, sized for the rig's two views side by side (even sizes: 4:2:0).
Status VideoSink::open(const Rig& rig) {
  view_w_[0] = rig.cameras.at(0).model.width_px;
  view_w_[1] = rig.cameras.at(1).model.width_px;
  width_ = (view_w_[0] + view_w_[1] + 1) / 2 * 2;
  height_ = (std::max(rig.cameras[0].model.height_px, rig.cameras[1].model.height_px) + 1) / 2 * 2;
  canvas_ = Image(width_, height_, PixelFormat::kRGB8);
  std::memset(canvas_.data(), 0, canvas_.size_bytes());
  if (int r = avformat_alloc_output_context2(&fmt_, nullptr, nullptr, o_.path.c_str()); r < 0 || !fmt_)
    return fail("no container for this file name (e.g. .mp4, .mkv)", r);
  const AVCodec* codec = avcodec_find_encoder_by_name("libx264");
  if (!codec) codec = avcodec_find_encoder(AV_CODEC_ID_H264);
  if (!codec)
    return make_error("video sink: ", o_.path, ": FFmpeg has no H.264 encoder (Debian: libavcodec59)");
  codec_ = avcodec_alloc_context3(codec);
  codec_->width = width_;
  codec_->height = height_;
  codec_->pix_fmt = AV_PIX_FMT_YUV420P;
  codec_->time_base = kTimeBase;
  codec_->framerate = {30, 1};  // a guess for rate control; the times are the pairs' own
  codec_->gop_size = 60;
  codec_->max_b_frames = 0;
  if (fmt_->oformat->flags & AVFMT_GLOBALHEADER) codec_->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
  av_opt_set(codec_->priv_data, "preset", "veryfast", 0);
  av_opt_set_int(codec_->priv_data, "crf", o_.crf, 0);
  if (int r = avcodec_open2(codec_, codec, nullptr); r < 0) return fail("cannot open the H.264 encoder", r);
  stream_ = avformat_new_stream(fmt_, nullptr);
  stream_->time_base = kTimeBase;
  if (int r = avcodec_parameters_from_context(stream_->codecpar, codec_); r < 0) return fail("stream", r);
  if (int r = avio_open(&fmt_->pb, o_.path.c_str(), AVIO_FLAG_WRITE); r < 0) return fail("cannot write", r);
  if (int r = avformat_write_header(fmt_, nullptr); r < 0) return fail("cannot write the header", r);
  header_written_ = true;
  frame_ = av_frame_alloc();
  frame_->format = AV_PIX_FMT_YUV420P;
  frame_->width = width_;
  frame_->height = height_;
  if (int r = av_frame_get_buffer(frame_, 0); r < 0) return fail("frame buffer", r);
  packet_ = av_packet_alloc();
  sws_ = sws_getContext(width_, height_, AV_PIX_FMT_RGB24, width_, height_, AV_PIX_FMT_YUV420P, SWS_BILINEAR,
                        nullptr, nullptr, nullptr);
  if (!sws_) return make_error("video sink: ", o_.path, ": no RGB to YUV 4:2:0 conversion");
  return {};
}

// Both whole augmented views (RGB: a Bayer view demosaiced, Mono replicated) onto the canvas.
Status VideoSink::compose(PairContext& pair) {
  pair.make_whole();
  int x0 = 0;
  for (int c = 0; c < 2; ++c) {
    const ViewResult& v = c == 0 ? pair.result->left : pair.result->right;
    Image rgb = to_rgb8(v.augmented);
    if (o_.masks && !v.mask.empty()) rgb = blend_over(rgb, visualize_receiver_occlusion(v.mask, c == 0));
    if (rgb.width() != view_w_[c] || rgb.height() > height_)
      return make_error("video sink: ", o_.path, ": a ", rgb.width(), "x", rgb.height(),
                        " view, the rig's camera is ", view_w_[c], " wide");
    for (int y = 0; y < rgb.height(); ++y)
      std::memcpy(canvas_.row(y) + static_cast<std::size_t>(x0) * 3, rgb.row(y),
                  static_cast<std::size_t>(rgb.width()) * 3);
    x0 += view_w_[c];
  }
  return {};
}

Status VideoSink::consume(PairContext& pair) {
  if (!pair.result) return {};
  if (Status st = compose(pair); !st) return st;
  if (int r = av_frame_make_writable(frame_); r < 0) return fail("frame buffer", r);
  const std::uint8_t* src[1] = {canvas_.data()};
  const int src_stride[1] = {static_cast<int>(canvas_.view().stride_bytes)};
  sws_scale(sws_, src, src_stride, 0, height_, frame_->data, frame_->linesize);
  // The pair's time from the first pair's; never backwards (a replay's seek or loop goes on).
  if (!first_t_ns_) first_t_ns_ = pair.raw.t_key_ns;
  std::int64_t pts = av_rescale_q(pair.raw.t_key_ns - *first_t_ns_, {1, 1'000'000'000}, kTimeBase);
  if (pts <= last_pts_) pts = last_pts_ + 1;
  // A frame lasts until the next; the last one as long as the one before it (else the container
  // would give it no time and players drop it).
  if (last_pts_ >= 0) interval_ = pts - last_pts_;
  frame_->pts = last_pts_ = pts;
  return encode(frame_);
}

// Hands a frame to the encoder (null: the end) and writes every packet it gives back.
Status VideoSink::encode(AVFrame* frame) {
  if (int r = avcodec_send_frame(codec_, frame); r < 0) return fail("encoding", r);
  for (;;) {
    const int r = avcodec_receive_packet(codec_, packet_);
    if (r == AVERROR(EAGAIN) || r == AVERROR_EOF) return {};
    if (r < 0) return fail("encoding", r);
    if (packet_->duration <= 0) packet_->duration = interval_;
    av_packet_rescale_ts(packet_, codec_->time_base, stream_->time_base);
    packet_->stream_index = stream_->index;
    const int w = av_interleaved_write_frame(fmt_, packet_);
    av_packet_unref(packet_);
    if (w < 0) return fail("write failed", w);
  }
}

Status VideoSink::close(PipelineReport& /*report*/) {
  if (closed_) return {};
  closed_ = true;
  Status st = encode(nullptr);
  if (int r = av_write_trailer(fmt_); r < 0 && st) st = fail("cannot finish the file", r);
  release_all();
  return st;
}

void VideoSink::release_all() {
  sws_freeContext(sws_);
  sws_ = nullptr;
  av_packet_free(&packet_);
  av_frame_free(&frame_);
  avcodec_free_context(&codec_);
  if (fmt_) {
    if (fmt_->pb) avio_closep(&fmt_->pb);
    avformat_free_context(fmt_);
    fmt_ = nullptr;
  }
}

}  // namespace

Expected<std::unique_ptr<FrameSink>> make_video_sink(const std::string& arg, const SinkSetup& setup) {
  auto options = parse_options(arg);
  if (!options) return options.error();
  auto sink = std::make_unique<VideoSink>(std::move(*options));
  if (Status st = sink->open(setup.rig); !st) return st.error();
  return std::unique_ptr<FrameSink>(std::move(sink));
}

}  // namespace augrig::pipeline
