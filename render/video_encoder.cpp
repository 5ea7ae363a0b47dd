// video_encoder.cpp - threaded libx264/MP4 encoder (see video_encoder.h).
#include "render/video_encoder.h"

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/log.h>
#include <libavutil/opt.h>
#include <libswscale/swscale.h>
}

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>

#include "render/av_error.h"
#include "sim/core_error.h"

namespace esim {
namespace {

std::int64_t nowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::string version(const char* name, unsigned v) {
  return std::string(name) + " " + std::to_string(AV_VERSION_MAJOR(v)) + "." +
         std::to_string(AV_VERSION_MINOR(v)) + "." + std::to_string(AV_VERSION_MICRO(v));
}

}  // namespace

void validateVideoRate(double fps) {
  ESIM_VERIFY(fps >= kMinVideoFps && fps <= kMaxVideoFps,
              "time.fps = " + messageNumber(fps) + ": a video needs " +
                  messageNumber(kMinVideoFps) + " to " + messageNumber(kMaxVideoFps) +
                  " frames per second; set output.video: false for other rates");
}

namespace {

// the options open() accepts (sizes, rates, quality, queue)
void checkOptions(const VideoEncoder::Options& o) {
  ESIM_VERIFY(!o.path.empty(), "video.path: empty output path");
  ESIM_VERIFY(o.width >= 16 && o.height >= 16 && o.width % 2 == 0 && o.height % 2 == 0,
              "video.width/height: " + std::to_string(o.width) + "x" + std::to_string(o.height) +
                  ", expected even sizes >= 16 (yuv420p halves the chroma)");
  validateVideoRate(o.fps);
  ESIM_VERIFY(o.crf >= 0 && o.crf <= 51,
              "video.crf: " + std::to_string(o.crf) + ", expected 0..51");
  ESIM_VERIFY(o.queueCapacity >= 1, "video.queue_capacity: must be at least 1");
}

// the wanted encoder, else (allowFallback) libopenh264, else mpeg4; a fallback's reason
// goes to notes and stderr
const AVCodec* findEncoder(const VideoEncoder::Options& o, std::string& notes) {
  const AVCodec* codec = avcodec_find_encoder_by_name(o.codec.c_str());
  if (!codec) {
    const std::string missing = "video: encoder '" + o.codec +
                                "' is not available in this FFmpeg "
                                "build (libavcodec " +
                                std::to_string(LIBAVCODEC_VERSION_MAJOR) + ")";
    ESIM_VERIFY(o.allowFallback, missing + "; install an FFmpeg with " + o.codec +
                                     " (Debian: libavcodec59 with libx264) or allow the fallback");
    for (const char* name : {"libopenh264", "mpeg4"}) {
      if ((codec = avcodec_find_encoder_by_name(name)) != nullptr) break;
    }
    ESIM_VERIFY(codec, missing + ", and neither libopenh264 nor mpeg4 is available");
    notes = missing + "; falling back to '" + codec->name + "'" +
            (std::string(codec->name) == "mpeg4" ? " (MPEG-4 Part 2, not H.264)" : "");
    std::cerr << "esim: warning: " << notes << "\n";
  }
  return codec;
}

// the fragmented MP4 `in` copied packet by packet into the regular MP4 `out` (its index
// in front: movflags +faststart) with the encoder's stream parameters `par` and rate. The
// fragmented file has no edit list, so its first frame shows at the encoder's delay (two
// frames with B-frames): every timestamp is moved back by the first packet's (the key
// frame shown first), which gives the regular file its edit list and frame 0 at t = 0, as
// the encoder made them. The bytes depend only on the packets (AVFMT_FLAG_BITEXACT when
// bitexact).
void remuxToRegularMp4(const std::string& in, const std::string& out, const AVCodecParameters* par,
                       AVRational frameRate, bool bitexact) {
  AVFormatContext* ic = nullptr;
  AVFormatContext* oc = nullptr;
  AVPacket* pkt = av_packet_alloc();
  const auto cleanup = [&] {
    av_packet_free(&pkt);
    avformat_close_input(&ic);
    if (oc) {
      if (oc->pb) avio_closep(&oc->pb);
      avformat_free_context(oc);
      oc = nullptr;
    }
  };
  try {
    ESIM_VERIFY(pkt, "video: out of memory allocating a packet");
    int rc = avformat_open_input(&ic, in.c_str(), nullptr, nullptr);
    ESIM_VERIFY(rc >= 0, "video: cannot read back '" + in + "': " + avError(rc));
    ESIM_VERIFY(ic->nb_streams == 1, "video: '" + in + "' has " + std::to_string(ic->nb_streams) +
                                         " streams, expected 1");
    const AVStream* is = ic->streams[0];
    rc = avformat_alloc_output_context2(&oc, nullptr, "mp4", out.c_str());
    ESIM_VERIFY(rc >= 0 && oc, "video: cannot create an MP4 muxer: " + avError(rc));
    if (bitexact) oc->flags |= AVFMT_FLAG_BITEXACT;
    AVStream* os = avformat_new_stream(oc, nullptr);
    ESIM_VERIFY(os, "video: cannot add a stream to the MP4 muxer");
    rc = avcodec_parameters_copy(os->codecpar, par);
    ESIM_VERIFY(rc >= 0, "video: codec parameters: " + avError(rc));
    // the extradata as the MP4 stores it (H.264: avcC), since the packets read back are
    // in the MP4's form (length-prefixed NAL units), not the encoder's Annex B
    if (is->codecpar->extradata_size > 0) {
      av_freep(&os->codecpar->extradata);
      os->codecpar->extradata = static_cast<std::uint8_t*>(
          av_mallocz(is->codecpar->extradata_size + AV_INPUT_BUFFER_PADDING_SIZE));
      ESIM_VERIFY(os->codecpar->extradata, "video: out of memory copying the extradata");
      std::memcpy(os->codecpar->extradata, is->codecpar->extradata, is->codecpar->extradata_size);
      os->codecpar->extradata_size = is->codecpar->extradata_size;
    }
    os->codecpar->codec_tag = 0;
    os->time_base = is->time_base;
    os->avg_frame_rate = frameRate;
    os->sample_aspect_ratio = par->sample_aspect_ratio;
    rc = avio_open(&oc->pb, out.c_str(), AVIO_FLAG_WRITE);
    ESIM_VERIFY(rc >= 0, "video.path: cannot open '" + out + "' for writing: " + avError(rc));
    AVDictionary* muxOpts = nullptr;
    av_dict_set(&muxOpts, "movflags", "+faststart", 0);
    rc = avformat_write_header(oc, &muxOpts);
    av_dict_free(&muxOpts);
    ESIM_VERIFY(rc >= 0, "video: cannot write the MP4 header to '" + out + "': " + avError(rc));
    std::int64_t shift = AV_NOPTS_VALUE;
    while ((rc = av_read_frame(ic, pkt)) >= 0) {
      if (shift == AV_NOPTS_VALUE) shift = pkt->pts != AV_NOPTS_VALUE ? pkt->pts : 0;
      if (pkt->pts != AV_NOPTS_VALUE) pkt->pts -= shift;
      if (pkt->dts != AV_NOPTS_VALUE) pkt->dts -= shift;
      pkt->stream_index = 0;
      av_packet_rescale_ts(pkt, is->time_base, os->time_base);
      pkt->pos = -1;
      rc = av_interleaved_write_frame(oc, pkt);
      ESIM_VERIFY(rc >= 0, "video: writing '" + out + "' failed: " + avError(rc));
    }
    ESIM_VERIFY(rc == AVERROR_EOF, "video: reading back '" + in + "' failed: " + avError(rc));
    rc = av_write_trailer(oc);
    ESIM_VERIFY(rc >= 0, "video: finishing '" + out + "' failed: " + avError(rc));
    rc = avio_closep(&oc->pb);
    ESIM_VERIFY(rc >= 0, "video: finishing '" + out + "' failed: " + avError(rc));
  } catch (...) {
    cleanup();
    throw;
  }
  cleanup();
}

}  // namespace

struct VideoEncoder::Av {
  AVFormatContext* fmt = nullptr;
  AVCodecContext* codec = nullptr;
  AVStream* stream = nullptr;
  SwsContext* sws = nullptr;
  AVFrame* frame = nullptr;
  AVPacket* packet = nullptr;
  std::int64_t nextPts = 0;
  bool headerWritten = false;

  // the codec context: size, time base, BT.709 tags, threads, and the rate control of
  // the encoder in use (codecName)
  void configureCodec(const AVCodec* encoder, const Options& o, const std::string& codecName);
  // the MP4 muxer on tmpPath, the opened encoder, its stream and the open output file
  void openContainer(const AVCodec* encoder, const Options& o, const std::string& tmpPath,
                     const std::string& codecName);
  // the fragmented MP4's header (see writeHeader); libav's return code
  int writeHeader();
  // colour conversion RGB24 (full range) -> YUV420P (limited), BT.709 matrix; the frame
  // and the packet
  void allocateFrames(const Options& o);

  ~Av() {
    sws_freeContext(sws);
    av_frame_free(&frame);
    av_packet_free(&packet);
    avcodec_free_context(&codec);
    if (fmt) {
      if (fmt->pb) avio_closep(&fmt->pb);
      avformat_free_context(fmt);
    }
  }
};

VideoEncoder::VideoEncoder() = default;

VideoEncoder::~VideoEncoder() {
  if (!isOpen()) return;
  try {
    close();
  } catch (const std::exception& e) {
    std::cerr << "esim: video " << opt_.path << " could not be finished: " << e.what() << "\n";
  }
}

std::string VideoEncoder::libraryVersions() {
  return version("libavcodec", avcodec_version()) + ", " +
         version("libavformat", avformat_version()) + ", " +
         version("libswscale", swscale_version());
}

void VideoEncoder::Av::configureCodec(const AVCodec* encoder, const Options& o,
                                      const std::string& codecName) {
  codec = avcodec_alloc_context3(encoder);
  ESIM_VERIFY(codec, "video: out of memory allocating the codec context");
  AVCodecContext* c = codec;
  c->width = o.width;
  c->height = o.height;
  c->pix_fmt = AV_PIX_FMT_YUV420P;
  // the exact rate as a fraction (29.97 -> 2997/100, 0.5 -> 1/2), never rounded to an int
  const AVRational rate = av_d2q(o.fps, 100000);
  c->time_base = AVRational{rate.den, rate.num};
  c->framerate = rate;
  c->sample_aspect_ratio = AVRational{1, 1};
  c->color_primaries = AVCOL_PRI_BT709;
  c->color_trc = AVCOL_TRC_BT709;
  c->colorspace = AVCOL_SPC_BT709;
  c->color_range = AVCOL_RANGE_MPEG;
  c->gop_size = std::max(1, static_cast<int>(std::lround(2 * o.fps)));
  c->thread_count = o.reproducible ? 1 : 0;
  if (o.reproducible) c->flags |= AV_CODEC_FLAG_BITEXACT;
  if (codecName == "libx264") {
    av_opt_set(c->priv_data, "preset", o.preset.c_str(), 0);
    av_opt_set_double(c->priv_data, "crf", o.crf, 0);
  } else if (codecName == "libopenh264") {
    c->bit_rate = static_cast<std::int64_t>(o.width * o.height * o.fps / 8);  // ~0.125 bit/px
  } else {  // mpeg4 and others: constant quantiser from crf (crf 20 -> q 3)
    c->flags |= AV_CODEC_FLAG_QSCALE;
    c->global_quality = FF_QP2LAMBDA * std::clamp(o.crf / 6, 2, 31);
  }
}

void VideoEncoder::Av::openContainer(const AVCodec* encoder, const Options& o,
                                     const std::string& tmpPath, const std::string& codecName) {
  AVCodecContext* c = codec;
  int rc = avformat_alloc_output_context2(&fmt, nullptr, "mp4", tmpPath.c_str());
  ESIM_VERIFY(rc >= 0 && fmt, "video: cannot create an MP4 muxer: " + avError(rc));
  if (o.reproducible) fmt->flags |= AVFMT_FLAG_BITEXACT;
  if (fmt->oformat->flags & AVFMT_GLOBALHEADER) c->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
  rc = avcodec_open2(c, encoder, nullptr);
  ESIM_VERIFY(rc >= 0, "video: cannot open encoder '" + codecName + "' (preset '" + o.preset +
                           "', crf " + std::to_string(o.crf) + "): " + avError(rc));
  stream = avformat_new_stream(fmt, nullptr);
  ESIM_VERIFY(stream, "video: cannot add a stream to the MP4 muxer");
  stream->time_base = c->time_base;
  stream->avg_frame_rate = c->framerate;
  rc = avcodec_parameters_from_context(stream->codecpar, c);
  ESIM_VERIFY(rc >= 0, "video: codec parameters: " + avError(rc));
  rc = avio_open(&fmt->pb, tmpPath.c_str(), AVIO_FLAG_WRITE);
  ESIM_VERIFY(rc >= 0, "video.path: cannot open '" + tmpPath + "' for writing: " + avError(rc));
}

int VideoEncoder::Av::writeHeader() {
  AVDictionary* muxOpts = nullptr;
  // fragmented while it grows: a fragment from each key frame, written out when the next
  // key frame comes (fmt->flush_packets), so a process killed mid-run leaves a file that
  // plays up to its last fragment; close() rewrites it as one regular MP4
  av_dict_set(&muxOpts, "movflags", "+frag_keyframe+empty_moov+default_base_moof", 0);
  fmt->flush_packets = 1;
  const int rc = avformat_write_header(fmt, &muxOpts);
  av_dict_free(&muxOpts);
  return rc;
}

void VideoEncoder::Av::allocateFrames(const Options& o) {
  sws = sws_getContext(o.width, o.height, AV_PIX_FMT_RGB24, o.width, o.height, AV_PIX_FMT_YUV420P,
                       SWS_BILINEAR | SWS_ACCURATE_RND | (o.reproducible ? SWS_BITEXACT : 0),
                       nullptr, nullptr, nullptr);
  ESIM_VERIFY(sws, "video: cannot create the RGB -> YUV420P converter");
  const int* bt709 = sws_getCoefficients(SWS_CS_ITU709);
  sws_setColorspaceDetails(sws, bt709, 1, bt709, 0, 0, 1 << 16, 1 << 16);
  frame = av_frame_alloc();
  packet = av_packet_alloc();
  ESIM_VERIFY(frame && packet, "video: out of memory allocating frames");
  frame->format = AV_PIX_FMT_YUV420P;
  frame->width = o.width;
  frame->height = o.height;
  frame->color_primaries = AVCOL_PRI_BT709;
  frame->color_trc = AVCOL_TRC_BT709;
  frame->colorspace = AVCOL_SPC_BT709;
  frame->color_range = AVCOL_RANGE_MPEG;
  const int rc = av_frame_get_buffer(frame, 0);
  ESIM_VERIFY(rc >= 0, "video: cannot allocate a frame: " + avError(rc));
}

void VideoEncoder::open(const Options& o) {
  ESIM_VERIFY(!isOpen(), "video: open() called on an encoder that is already open");
  checkOptions(o);
  opt_ = o;
  // libx264 and the muxer log every file at "info" level; keep stderr for warnings
  // unless the application chose a level itself
  if (av_log_get_level() == AV_LOG_INFO) av_log_set_level(AV_LOG_WARNING);
  av_ = std::make_unique<Av>();
  Av& a = *av_;
  codecName_.clear();
  notes_.clear();
  encodeNs_ = convertNs_ = pushWaitNs_ = 0;
  framesEncoded_ = 0;
  framesSpooled_ = 0;
  closing_ = false;
  error_ = nullptr;
  queue_.clear();

  // 1. encoder, with the documented fallback chain
  const AVCodec* codec = findEncoder(o, notes_);
  codecName_ = codec->name;
  a.configureCodec(codec, o, codecName_);

  // 2. container on the temporary name
  tmpPath_ = o.path + ".partial";
  a.openContainer(codec, o, tmpPath_, codecName_);
  const int rc = a.writeHeader();
  if (rc < 0) {
    av_.reset();
    std::error_code ec;
    std::filesystem::remove(tmpPath_, ec);
    throw Error("video: cannot write the MP4 header to '" + tmpPath_ + "': " + avError(rc));
  }
  a.headerWritten = true;

  // 3. colour conversion and the frame buffers
  a.allocateFrames(o);

  // 4. deferred: the file of raw frames
  if (o.deferred) {
    spool_ = std::fopen(spoolPath().c_str(), "w+b");
    if (!spool_) {
      const int e = errno;
      av_.reset();
      std::error_code ec;
      std::filesystem::remove(tmpPath_, ec);
      throw Error("video: cannot create '" + spoolPath() + "' (the frames kept until the end, " +
                  "output.encode: after): " + std::strerror(e));
    }
  }

  // 5. the encoder thread
  thread_ = std::thread([this] { run(); });
}

void VideoEncoder::push(std::vector<std::uint8_t> rgb) {
  ESIM_VERIFY(isOpen(), "video: push() on an encoder that is not open");
  ESIM_VERIFY(rgb.size() == static_cast<size_t>(opt_.width) * opt_.height * 3,
              "video: frame has " + std::to_string(rgb.size()) + " bytes, expected " +
                  std::to_string(opt_.width) + "x" + std::to_string(opt_.height) + "x3 (RGB24)");
  std::unique_lock<std::mutex> lock(mutex_);
  const std::int64_t t0 = nowNs();
  notFull_.wait(lock,
                [&] { return error_ || static_cast<int>(queue_.size()) < opt_.queueCapacity; });
  pushWaitNs_ += nowNs() - t0;
  if (error_) {
    lock.unlock();
    close();  // joins, removes the partial file and rethrows
    return;
  }
  queue_.push_back(std::move(rgb));
  notEmpty_.notify_one();
}

void VideoEncoder::close() {
  if (!isOpen()) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    closing_ = true;
  }
  notEmpty_.notify_one();
  thread_.join();
  std::exception_ptr err = error_;
  const std::string regularPath = opt_.path + ".regular.partial";
  bool keepFragmented = false;  // complete, and its rewrite failed: it stays, and plays
  if (!err) {
    // the trailer was written by the thread; close the fragmented file, rewrite it as one
    // regular MP4 and publish that
    avio_closep(&av_->fmt->pb);
    try {
      remuxToRegularMp4(tmpPath_, regularPath, av_->stream->codecpar, av_->codec->framerate,
                        opt_.reproducible);
      std::error_code ec;
      std::filesystem::rename(regularPath, opt_.path, ec);
      if (ec)
        throw Error("video.path: cannot rename '" + regularPath + "' to '" + opt_.path +
                    "': " + ec.message());
    } catch (const std::exception& e) {
      keepFragmented = true;
      const auto* known = dynamic_cast<const Error*>(&e);
      err = std::make_exception_ptr(Error(std::string(e.what()) + "; every frame is kept in '" +
                                              tmpPath_ + "' (a fragmented MP4, which plays)",
                                          known ? known->kind() : ErrorKind::Run));
    }
  }
  av_.reset();
  std::error_code ec;
  if (spool_) {  // deferred: its frames are encoded, or the video failed
    std::fclose(spool_);
    spool_ = nullptr;
    std::filesystem::remove(spoolPath(), ec);
  }
  if (std::filesystem::is_regular_file(regularPath, ec)) std::filesystem::remove(regularPath, ec);
  if (!keepFragmented) std::filesystem::remove(tmpPath_, ec);
  if (err) std::rethrow_exception(err);
}

void VideoEncoder::fail() {
  std::lock_guard<std::mutex> lock(mutex_);
  error_ = std::current_exception();
  queue_.clear();
  notFull_.notify_all();
}

// sends the current frame (or the flush) and writes all packets that come out
void VideoEncoder::encodeFrame(bool flush) {
  Av& a = *av_;
  int rc = avcodec_send_frame(a.codec, flush ? nullptr : a.frame);
  ESIM_VERIFY(rc >= 0, "video: encoder '" + codecName_ + "' rejected a frame: " + avError(rc));
  while (true) {
    rc = avcodec_receive_packet(a.codec, a.packet);
    if (rc == AVERROR(EAGAIN) || rc == AVERROR_EOF) break;
    ESIM_VERIFY(rc >= 0, "video: encoding failed: " + avError(rc));
    if (a.packet->duration <= 0) a.packet->duration = 1;  // one frame, in 1/fps
    av_packet_rescale_ts(a.packet, a.codec->time_base, a.stream->time_base);
    a.packet->stream_index = a.stream->index;
    rc = av_interleaved_write_frame(a.fmt, a.packet);
    ESIM_VERIFY(rc >= 0, "video: writing '" + tmpPath_ + "' failed: " + avError(rc));
  }
}

// one RGB24 frame: colour conversion, then the encoder and the muxer
void VideoEncoder::convertAndEncode(const std::vector<std::uint8_t>& rgb) {
  Av& a = *av_;
  const std::int64_t t0 = nowNs();
  int rc = av_frame_make_writable(a.frame);
  ESIM_VERIFY(rc >= 0, "video: frame not writable: " + avError(rc));
  const std::uint8_t* src[4] = {rgb.data(), nullptr, nullptr, nullptr};
  const int srcStride[4] = {opt_.width * 3, 0, 0, 0};
  sws_scale(a.sws, src, srcStride, 0, opt_.height, a.frame->data, a.frame->linesize);
  a.frame->pts = a.nextPts++;
  a.frame->pkt_duration = 1;
  const std::int64_t t1 = nowNs();
  convertNs_ += t1 - t0;
  encodeFrame(false);
  encodeNs_ += nowNs() - t1;
  ++framesEncoded_;
}

void VideoEncoder::run() {
  Av& a = *av_;
  try {
    while (true) {
      std::vector<std::uint8_t> rgb;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        notEmpty_.wait(lock, [&] { return closing_ || !queue_.empty(); });
        if (queue_.empty()) break;  // closing and drained
        rgb = std::move(queue_.front());
        queue_.pop_front();
        notFull_.notify_one();
      }
      if (!spool_) {
        convertAndEncode(rgb);
        continue;
      }
      // deferred: kept raw, in order, for close()
      if (std::fwrite(rgb.data(), 1, rgb.size(), spool_) != rgb.size() || std::fflush(spool_) != 0)
        throw Error("video: writing frame " + std::to_string(framesSpooled_.load()) + " to '" +
                    spoolPath() + "' (the frames kept until the end, output.encode: after) " +
                    "failed: " + std::strerror(errno));
      ++framesSpooled_;
    }
    if (spool_) {  // closing: every frame kept, encoded in order
      ESIM_VERIFY(std::fseek(spool_, 0, SEEK_SET) == 0,
                  "video: cannot read back '" + spoolPath() + "': " + std::strerror(errno));
      std::vector<std::uint8_t> rgb(static_cast<size_t>(opt_.width) * opt_.height * 3);
      for (int f = 0; f < framesSpooled_.load(); ++f) {
        ESIM_VERIFY(
            std::fread(rgb.data(), 1, rgb.size(), spool_) == rgb.size(),
            "video: reading frame " + std::to_string(f) + " back from '" + spoolPath() +
                "' failed (" +
                (std::ferror(spool_) ? std::strerror(errno) : std::string("the file is short")) +
                ")");
        convertAndEncode(rgb);
      }
    }
    const std::int64_t t0 = nowNs();
    encodeFrame(true);
    const int rc = av_write_trailer(a.fmt);
    ESIM_VERIFY(rc >= 0, "video: finishing '" + tmpPath_ + "' failed: " + avError(rc));
    encodeNs_ += nowNs() - t0;
  } catch (...) {
    fail();
  }
}

}  // namespace esim
