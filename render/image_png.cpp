// image_png.cpp - PNG encode/decode with libavcodec (see image_png.h).
#include "render/image_png.h"

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavutil/imgutils.h>
#include <libavutil/opt.h>
#include <libswscale/swscale.h>
}

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>

#include "render/av_error.h"
#include "sim/core_error.h"

namespace esim {
namespace {

struct CodecCtxFree {
  void operator()(AVCodecContext* c) const { avcodec_free_context(&c); }
};
struct FrameFree {
  void operator()(AVFrame* f) const { av_frame_free(&f); }
};
struct PacketFree {
  void operator()(AVPacket* p) const { av_packet_free(&p); }
};

}  // namespace

namespace {

// encodes one image of the given pixel format (data rows top first, linesize bytes apart)
// and writes it to path through path.tmp; fast: the "up" row filter and zlib level 3 (label
// images, written every frame: ~4x faster than libavcodec's default, no filter and level 6,
// and smaller for smooth depth), else libavcodec's defaults
void encodePng(const std::string& path, AVPixelFormat format, const std::uint8_t* data,
               int linesize, int width, int height, bool fast = false) {
  const AVCodec* codec = avcodec_find_encoder(AV_CODEC_ID_PNG);
  ESIM_VERIFY(codec, "writePng(" + path + "): libavcodec has no PNG encoder");
  std::unique_ptr<AVCodecContext, CodecCtxFree> ctx(avcodec_alloc_context3(codec));
  ctx->width = width;
  ctx->height = height;
  ctx->pix_fmt = format;
  ctx->time_base = AVRational{1, 1};
  ctx->flags |= AV_CODEC_FLAG_BITEXACT;  // no software tag: same image, same bytes
  if (fast) {
    ctx->compression_level = 3;
    av_opt_set(ctx->priv_data, "pred", "up", 0);
  }
  int rc = avcodec_open2(ctx.get(), codec, nullptr);
  ESIM_VERIFY(rc >= 0, "writePng(" + path + "): cannot open PNG encoder: " + avError(rc));
  std::unique_ptr<AVFrame, FrameFree> frame(av_frame_alloc());
  frame->format = format;
  frame->width = width;
  frame->height = height;
  // the frame borrows the caller's bytes (the encoder only reads them)
  frame->data[0] = const_cast<std::uint8_t*>(data);
  frame->linesize[0] = linesize;
  std::unique_ptr<AVPacket, PacketFree> pkt(av_packet_alloc());
  rc = avcodec_send_frame(ctx.get(), frame.get());
  ESIM_VERIFY(rc >= 0, "writePng(" + path + "): encoding failed: " + avError(rc));
  rc = avcodec_receive_packet(ctx.get(), pkt.get());
  ESIM_VERIFY(rc >= 0, "writePng(" + path + "): encoding failed: " + avError(rc));
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    ESIM_VERIFY(out.good(), "writePng(" + path + "): cannot open " + tmp + " for writing");
    out.write(reinterpret_cast<const char*>(pkt->data), pkt->size);
    out.close();  // what is still buffered fails here when the disk is full
    if (!out) {   // (a cut PNG was renamed as whole, the temporary file was left behind)
      std::error_code ec;
      std::filesystem::remove(tmp, ec);
      throw Error("writePng(" + path + "): write failed (disk full?)", ErrorKind::Run);
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    throw Error("writePng(" + path + "): cannot rename the temporary file");
  }
}

// checks a one-channel image's size
void checkPlane(const std::string& path, size_t size, int width, int height) {
  ESIM_VERIFY(width > 0 && height > 0 && size == static_cast<size_t>(width) * height,
              "writePng(" + path + "): image has " + std::to_string(size) + " values, expected " +
                  std::to_string(width) + "x" + std::to_string(height));
}

}  // namespace

void writePng(const std::string& path, const std::vector<std::uint8_t>& rgb, int width,
              int height) {
  ESIM_VERIFY(width > 0 && height > 0 && rgb.size() == static_cast<size_t>(width) * height * 3,
              "writePng(" + path + "): image has " + std::to_string(rgb.size()) +
                  " bytes, expected " + std::to_string(width) + "x" + std::to_string(height) +
                  "x3");
  encodePng(path, AV_PIX_FMT_RGB24, rgb.data(), width * 3, width, height);
}

void writePngGray8(const std::string& path, const std::vector<std::uint8_t>& values, int width,
                   int height) {
  checkPlane(path, values.size(), width, height);
  encodePng(path, AV_PIX_FMT_GRAY8, values.data(), width, width, height, true);
}

void writePngGray16(const std::string& path, const std::vector<std::uint16_t>& values, int width,
                    int height) {
  checkPlane(path, values.size(), width, height);
  std::vector<std::uint8_t> be(values.size() * 2);  // PNG's byte order
  for (size_t i = 0; i < values.size(); ++i) {
    be[2 * i] = static_cast<std::uint8_t>(values[i] >> 8);
    be[2 * i + 1] = static_cast<std::uint8_t>(values[i] & 0xff);
  }
  encodePng(path, AV_PIX_FMT_GRAY16BE, be.data(), width * 2, width, height, true);
}

namespace {

// the decoded frame of a PNG file
std::unique_ptr<AVFrame, FrameFree> decodePng(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  ESIM_VERIFY(in.good(), "readPng(" + path + "): cannot open the file");
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                  std::istreambuf_iterator<char>());
  ESIM_VERIFY(bytes.size() > 8 && std::memcmp(bytes.data(), "\x89PNG", 4) == 0,
              "readPng(" + path + "): not a PNG file");
  const AVCodec* codec = avcodec_find_decoder(AV_CODEC_ID_PNG);
  ESIM_VERIFY(codec, "readPng(" + path + "): libavcodec has no PNG decoder");
  std::unique_ptr<AVCodecContext, CodecCtxFree> ctx(avcodec_alloc_context3(codec));
  int rc = avcodec_open2(ctx.get(), codec, nullptr);
  ESIM_VERIFY(rc >= 0, "readPng(" + path + "): cannot open PNG decoder: " + avError(rc));
  std::unique_ptr<AVPacket, PacketFree> pkt(av_packet_alloc());
  bytes.resize(bytes.size() + AV_INPUT_BUFFER_PADDING_SIZE, 0);
  pkt->data = bytes.data();
  pkt->size = static_cast<int>(bytes.size() - AV_INPUT_BUFFER_PADDING_SIZE);
  rc = avcodec_send_packet(ctx.get(), pkt.get());
  ESIM_VERIFY(rc >= 0, "readPng(" + path + "): decoding failed: " + avError(rc));
  avcodec_send_packet(ctx.get(), nullptr);
  std::unique_ptr<AVFrame, FrameFree> frame(av_frame_alloc());
  rc = avcodec_receive_frame(ctx.get(), frame.get());
  ESIM_VERIFY(rc >= 0, "readPng(" + path + "): decoding failed: " + avError(rc));
  return frame;
}

}  // namespace

RgbImage readPng(const std::string& path) {
  const std::unique_ptr<AVFrame, FrameFree> frame = decodePng(path);
  RgbImage img;
  img.width = frame->width;
  img.height = frame->height;
  img.rgb.resize(static_cast<size_t>(img.width) * img.height * 3);
  SwsContext* sws =
      sws_getContext(img.width, img.height, static_cast<AVPixelFormat>(frame->format), img.width,
                     img.height, AV_PIX_FMT_RGB24, SWS_POINT, nullptr, nullptr, nullptr);
  ESIM_VERIFY(sws, "readPng(" + path + "): unsupported pixel format");
  std::uint8_t* dst[4] = {img.rgb.data(), nullptr, nullptr, nullptr};
  int dstStride[4] = {img.width * 3, 0, 0, 0};
  sws_scale(sws, frame->data, frame->linesize, 0, img.height, dst, dstStride);
  sws_freeContext(sws);
  return img;
}

GrayImage readPngGray(const std::string& path) {
  const std::unique_ptr<AVFrame, FrameFree> frame = decodePng(path);
  const int format = frame->format;
  ESIM_VERIFY(format == AV_PIX_FMT_GRAY8 || format == AV_PIX_FMT_GRAY16BE,
              "readPngGray(" + path + "): not an 8- or 16-bit grey PNG");
  GrayImage img;
  img.width = frame->width;
  img.height = frame->height;
  img.bitDepth = format == AV_PIX_FMT_GRAY8 ? 8 : 16;
  img.values.resize(static_cast<size_t>(img.width) * img.height);
  for (int y = 0; y < img.height; ++y) {
    const std::uint8_t* row = frame->data[0] + static_cast<ptrdiff_t>(y) * frame->linesize[0];
    std::uint16_t* out = &img.values[static_cast<size_t>(y) * img.width];
    for (int x = 0; x < img.width; ++x)
      out[x] = img.bitDepth == 8 ? row[x]
                                 : static_cast<std::uint16_t>((row[2 * x] << 8) | row[2 * x + 1]);
  }
  return img;
}

}  // namespace esim
