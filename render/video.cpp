// MP4 video through FFmpeg: H.264 (libx264) or MPEG-4 part 2 when no H.264 encoder opens; decoding probe.
extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/imgutils.h>
#include <libavutil/opt.h>
#include <libswscale/swscale.h>
}

#include <cstdio>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "render/writers.hpp"

namespace lumen::render {

namespace {

std::string av_error_text(int code) {
  char buf[AV_ERROR_MAX_STRING_SIZE] = {0};
  av_strerror(code, buf, sizeof(buf));
  return buf;
}

// Quiet FFmpeg's per-encoder banners (libx264 prints several lines), unless the program chose a level itself.
void quiet_ffmpeg_logs() {
  static std::once_flag once;
  std::call_once(once, [] {
    if (av_log_get_level() == AV_LOG_INFO) av_log_set_level(AV_LOG_ERROR);
  });
}

}  // namespace

struct VideoEncoder::Impl {
  std::string path, tmp;
  int width = 0, height = 0, fps = 0;
  AVFormatContext* fmt = nullptr;
  AVCodecContext* enc = nullptr;
  AVStream* stream = nullptr;
  AVFrame* frame = nullptr;
  AVPacket* packet = nullptr;
  SwsContext* sws = nullptr;
  std::string codec;     // encoder name actually used ("libx264", "mpeg4", ...)
  bool header_written = false;
  bool closed = false;
  long next_pts = 0;     // frames sent so far, in codec time base (1 / fps)

  [[noreturn]] void fail(const std::string& what, int code) const {
    throw std::runtime_error("VideoEncoder(" + path + "): " + what + ": " + av_error_text(code));
  }
  bool open_encoder(const AVCodec* codec_candidate);
  void drain(bool flushing);
  void release();
};

bool VideoEncoder::Impl::open_encoder(const AVCodec* c) {
  // Configure one candidate encoder; false (and freed) when it does not open.
  if (c == nullptr) return false;
  AVCodecContext* ctx = avcodec_alloc_context3(c);
  if (ctx == nullptr) return false;
  ctx->width = width;
  ctx->height = height;
  ctx->time_base = AVRational{1, fps};
  ctx->framerate = AVRational{fps, 1};
  ctx->pix_fmt = AV_PIX_FMT_YUV420P;
  ctx->gop_size = 2 * fps;
  ctx->thread_count = 1;  // one core: the writer thread must not starve the simulation thread
  ctx->color_range = AVCOL_RANGE_MPEG;
  ctx->colorspace = AVCOL_SPC_SMPTE170M;  // swscale's default RGB -> YUV matrix is BT.601
  ctx->color_primaries = AVCOL_PRI_SMPTE170M;
  ctx->color_trc = AVCOL_TRC_SMPTE170M;
  if (fmt->oformat->flags & AVFMT_GLOBALHEADER) ctx->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
  AVDictionary* opts = nullptr;
  if (c->id == AV_CODEC_ID_H264) {
    av_dict_set(&opts, "preset", "veryfast", 0);
    av_dict_set(&opts, "crf", "20", 0);
  } else {
    ctx->bit_rate = static_cast<int64_t>(width) * height * fps / 4;  // about 0.25 bit per pixel
  }
  const int ret = avcodec_open2(ctx, c, &opts);
  av_dict_free(&opts);
  if (ret < 0) {
    avcodec_free_context(&ctx);
    return false;
  }
  enc = ctx;
  codec = c->name;
  return true;
}

VideoEncoder::VideoEncoder(const std::string& path, int width, int height, int fps) : impl_(std::make_unique<Impl>()) {
  // Validate the parameters at the boundary.
  if (path.empty()) throw std::invalid_argument("VideoEncoder path must not be empty");
  if (width <= 0 || width % 2 != 0) throw std::invalid_argument("VideoEncoder width must be positive and even (value " + std::to_string(width) + ")");
  if (height <= 0 || height % 2 != 0)
    throw std::invalid_argument("VideoEncoder height must be positive and even (value " + std::to_string(height) + ")");
  if (fps <= 0 || fps > 1000) throw std::invalid_argument("VideoEncoder fps must be in [1, 1000] (value " + std::to_string(fps) + ")");
  quiet_ffmpeg_logs();
  Impl& m = *impl_;
  m.path = path;
  m.tmp = path + ".tmp";
  m.width = width;
  m.height = height;
  m.fps = fps;
  try {
    // MP4 container, chosen explicitly since the temporary name has no .mp4 extension.
    int ret = avformat_alloc_output_context2(&m.fmt, nullptr, "mp4", m.tmp.c_str());
    if (ret < 0 || m.fmt == nullptr) m.fail("cannot allocate the MP4 muxer", ret);

    // Encoder: libx264, else any H.264 encoder that opens, else MPEG-4 part 2 (reported by codec()).
    if (!m.open_encoder(avcodec_find_encoder_by_name("libx264")) && !m.open_encoder(avcodec_find_encoder(AV_CODEC_ID_H264)) &&
        !m.open_encoder(avcodec_find_encoder(AV_CODEC_ID_MPEG4))) {
      throw std::runtime_error("VideoEncoder(" + path + "): no H.264 or MPEG-4 encoder could be opened");
    }

    // Stream, frame, packet and the RGB24 -> YUV420P converter.
    m.stream = avformat_new_stream(m.fmt, nullptr);
    if (m.stream == nullptr) throw std::runtime_error("VideoEncoder(" + path + "): cannot add a stream");
    m.stream->time_base = m.enc->time_base;
    m.stream->avg_frame_rate = m.enc->framerate;
    ret = avcodec_parameters_from_context(m.stream->codecpar, m.enc);
    if (ret < 0) m.fail("cannot copy codec parameters", ret);
    m.frame = av_frame_alloc();
    m.packet = av_packet_alloc();
    if (m.frame == nullptr || m.packet == nullptr) throw std::runtime_error("VideoEncoder(" + path + "): out of memory");
    m.frame->format = AV_PIX_FMT_YUV420P;
    m.frame->width = width;
    m.frame->height = height;
    ret = av_frame_get_buffer(m.frame, 0);
    if (ret < 0) m.fail("cannot allocate a frame", ret);
    m.sws = sws_getContext(width, height, AV_PIX_FMT_RGB24, width, height, AV_PIX_FMT_YUV420P, SWS_BILINEAR, nullptr, nullptr, nullptr);
    if (m.sws == nullptr) throw std::runtime_error("VideoEncoder(" + path + "): cannot create the RGB to YUV converter");

    // Open the temporary file and write the header.
    ret = avio_open(&m.fmt->pb, m.tmp.c_str(), AVIO_FLAG_WRITE);
    if (ret < 0) m.fail("cannot open " + m.tmp, ret);
    ret = avformat_write_header(m.fmt, nullptr);
    if (ret < 0) m.fail("cannot write the MP4 header", ret);
    m.header_written = true;
  } catch (...) {
    m.release();
    std::remove(m.tmp.c_str());
    throw;
  }
}

void VideoEncoder::Impl::drain(bool flushing) {
  // Move every packet the encoder has ready into the muxer.
  for (;;) {
    int ret = avcodec_receive_packet(enc, packet);
    if (ret == AVERROR(EAGAIN) || (flushing && ret == AVERROR_EOF)) return;
    if (ret < 0) fail("encoding failed", ret);
    av_packet_rescale_ts(packet, enc->time_base, stream->time_base);
    packet->stream_index = stream->index;
    ret = av_interleaved_write_frame(fmt, packet);  // takes ownership of the packet's data
    if (ret < 0) fail("cannot write to " + tmp, ret);
  }
}

void VideoEncoder::add(const Image& image) {
  Impl& m = *impl_;
  if (m.closed) throw std::logic_error("VideoEncoder(" + m.path + "): add() after close()");
  if (image.width != m.width || image.height != m.height || image.rgb.size() != static_cast<size_t>(m.width) * m.height * 3)
    throw std::invalid_argument("VideoEncoder(" + m.path + "): image must be " + std::to_string(m.width) + "x" + std::to_string(m.height) +
                                " RGB (value " + std::to_string(image.width) + "x" + std::to_string(image.height) + ", " +
                                std::to_string(image.rgb.size()) + " bytes)");
  // Convert to YUV420P into a frame the encoder no longer references, then encode.
  int ret = av_frame_make_writable(m.frame);
  if (ret < 0) m.fail("cannot get a writable frame", ret);
  const uint8_t* src[1] = {image.rgb.data()};
  const int src_stride[1] = {3 * m.width};
  sws_scale(m.sws, src, src_stride, 0, m.height, m.frame->data, m.frame->linesize);
  m.frame->pts = m.next_pts++;
  ret = avcodec_send_frame(m.enc, m.frame);
  if (ret < 0) m.fail("cannot send a frame to the encoder", ret);
  m.drain(false);
}

void VideoEncoder::close() {
  Impl& m = *impl_;
  if (m.closed) return;
  m.closed = true;
  try {
    // Flush the encoder, finish the MP4, close the file, then move it onto the final name.
    int ret = avcodec_send_frame(m.enc, nullptr);
    if (ret < 0) m.fail("cannot flush the encoder", ret);
    m.drain(true);
    ret = av_write_trailer(m.fmt);
    if (ret < 0) m.fail("cannot write the MP4 trailer", ret);
    ret = avio_closep(&m.fmt->pb);
    if (ret < 0) m.fail("cannot close " + m.tmp, ret);
    m.release();
    if (std::rename(m.tmp.c_str(), m.path.c_str()) != 0)
      throw std::runtime_error("VideoEncoder(" + m.path + "): cannot rename " + m.tmp + " onto it");
  } catch (...) {
    m.release();
    std::remove(m.tmp.c_str());
    throw;
  }
}

std::string VideoEncoder::codec() const { return impl_->codec; }

void VideoEncoder::Impl::release() {
  // Free every FFmpeg object (safe to call twice).
  if (fmt != nullptr && fmt->pb != nullptr) avio_closep(&fmt->pb);
  avformat_free_context(fmt);
  fmt = nullptr;
  stream = nullptr;
  avcodec_free_context(&enc);
  av_frame_free(&frame);
  av_packet_free(&packet);
  sws_freeContext(sws);
  sws = nullptr;
}

VideoEncoder::~VideoEncoder() {
  // Abandon an unfinished video: nothing is left under either name.
  if (impl_ && !impl_->closed) {
    impl_->release();
    std::remove(impl_->tmp.c_str());
  }
}

VideoInfo probe_video(const std::string& path) {
  // Open the file and find its video stream.
  AVFormatContext* fmt = nullptr;
  int ret = avformat_open_input(&fmt, path.c_str(), nullptr, nullptr);
  if (ret < 0) throw std::runtime_error("probe_video(" + path + "): cannot open: " + av_error_text(ret));
  AVCodecContext* dec = nullptr;
  AVPacket* packet = av_packet_alloc();
  AVFrame* frame = av_frame_alloc();
  auto cleanup = [&]() {
    av_frame_free(&frame);
    av_packet_free(&packet);
    avcodec_free_context(&dec);
    avformat_close_input(&fmt);
  };
  auto fail = [&](const std::string& what, int code) {
    cleanup();
    throw std::runtime_error("probe_video(" + path + "): " + what + (code < 0 ? ": " + av_error_text(code) : std::string()));
  };
  if (packet == nullptr || frame == nullptr) fail("out of memory", 0);
  ret = avformat_find_stream_info(fmt, nullptr);
  if (ret < 0) fail("cannot read stream info", ret);
  const AVCodec* decoder = nullptr;
  const int index = av_find_best_stream(fmt, AVMEDIA_TYPE_VIDEO, -1, -1, &decoder, 0);
  if (index < 0 || decoder == nullptr) fail("no decodable video stream", index);
  dec = avcodec_alloc_context3(decoder);
  if (dec == nullptr) fail("out of memory", 0);
  ret = avcodec_parameters_to_context(dec, fmt->streams[index]->codecpar);
  if (ret < 0) fail("bad codec parameters", ret);
  ret = avcodec_open2(dec, decoder, nullptr);
  if (ret < 0) fail("cannot open the decoder", ret);

  VideoInfo info;
  info.codec = avcodec_get_name(fmt->streams[index]->codecpar->codec_id);
  // Decode every packet of the stream, then flush, counting decoded frames.
  auto receive_all = [&]() {
    for (;;) {
      const int r = avcodec_receive_frame(dec, frame);
      if (r == AVERROR(EAGAIN) || r == AVERROR_EOF) return;
      if (r < 0) fail("decoding failed", r);
      ++info.frames;
      info.width = frame->width;
      info.height = frame->height;
      av_frame_unref(frame);
    }
  };
  while ((ret = av_read_frame(fmt, packet)) >= 0) {
    if (packet->stream_index == index) {
      const int r = avcodec_send_packet(dec, packet);
      av_packet_unref(packet);
      if (r < 0) fail("cannot decode a packet", r);
      receive_all();
    } else {
      av_packet_unref(packet);
    }
  }
  if (ret != AVERROR_EOF) fail("cannot read a packet", ret);
  ret = avcodec_send_packet(dec, nullptr);
  if (ret < 0) fail("cannot flush the decoder", ret);
  receive_all();
  cleanup();
  return info;
}

}  // namespace lumen::render
