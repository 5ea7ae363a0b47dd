// Tests for render/video_encoder.cpp: read the MP4 back with libavformat and check
// codec, frame count, duration, pixel format, colour tags, faststart, BT.709
// matrix, reproducible bytes, fallback and error handling, and the partial file that
// plays while the video grows.
#include "render/video_encoder.h"

#include <gtest/gtest.h>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
}

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <thread>

#include "render/image_hash.h"
#include "sim/core_error.h"

namespace esim {
namespace {

constexpr int kW = 160, kH = 120;

std::string tempPath(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / "esim_video_test";
  std::filesystem::create_directories(dir);
  return (dir / name).string();
}

// frame i: a moving colour ramp, so every frame differs
std::vector<std::uint8_t> frameAt(int i) {
  std::vector<std::uint8_t> img(kW * kH * 3);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      std::uint8_t* p = &img[(y * kW + x) * 3];
      p[0] = static_cast<std::uint8_t>((x * 2 + i * 5) & 255);
      p[1] = static_cast<std::uint8_t>(y * 2);
      p[2] = static_cast<std::uint8_t>(128 + 100 * std::sin(0.1 * x + 0.2 * i));
    }
  return img;
}

VideoEncoder::Options smallOptions(const std::string& path) {
  VideoEncoder::Options o;
  o.path = path;
  o.width = kW;
  o.height = kH;
  o.fps = 30;
  o.crf = 20;
  o.preset = "veryfast";
  return o;
}

void encode(const VideoEncoder::Options& o, int frames, VideoEncoder* enc = nullptr) {
  VideoEncoder local;
  VideoEncoder& e = enc ? *enc : local;
  e.open(o);
  for (int i = 0; i < frames; ++i) e.push(frameAt(i));
  e.close();
}

std::vector<char> fileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

struct Probe {
  AVCodecID codec = AV_CODEC_ID_NONE;
  int packets = 0, decoded = 0;
  double streamSeconds = 0, formatSeconds = 0, fps = 0;
  AVPixelFormat pixFmt = AV_PIX_FMT_NONE;
  AVColorPrimaries primaries = AVCOL_PRI_UNSPECIFIED;
  AVColorTransferCharacteristic trc = AVCOL_TRC_UNSPECIFIED;
  AVColorSpace space = AVCOL_SPC_UNSPECIFIED;
  AVColorRange range = AVCOL_RANGE_UNSPECIFIED;
  int centreLuma = -1;  // Y of the first decoded frame at the image centre
};

Probe probe(const std::string& path) {
  Probe p;
  AVFormatContext* fmt = nullptr;
  EXPECT_GE(avformat_open_input(&fmt, path.c_str(), nullptr, nullptr), 0) << path;
  if (!fmt) return p;
  EXPECT_GE(avformat_find_stream_info(fmt, nullptr), 0);
  const int si = av_find_best_stream(fmt, AVMEDIA_TYPE_VIDEO, -1, -1, nullptr, 0);
  EXPECT_GE(si, 0);
  AVStream* st = fmt->streams[si];
  const AVCodecParameters* par = st->codecpar;
  p.codec = par->codec_id;
  p.pixFmt = static_cast<AVPixelFormat>(par->format);
  p.primaries = par->color_primaries;
  p.trc = par->color_trc;
  p.space = par->color_space;
  p.range = par->color_range;
  p.streamSeconds = st->duration * av_q2d(st->time_base);
  p.formatSeconds = fmt->duration / static_cast<double>(AV_TIME_BASE);
  p.fps = av_q2d(st->avg_frame_rate);
  const AVCodec* dec = avcodec_find_decoder(par->codec_id);
  AVCodecContext* ctx = avcodec_alloc_context3(dec);
  avcodec_parameters_to_context(ctx, par);
  ctx->thread_count = 1;
  EXPECT_GE(avcodec_open2(ctx, dec, nullptr), 0);
  AVPacket* pkt = av_packet_alloc();
  AVFrame* frame = av_frame_alloc();
  auto drain = [&] {
    while (avcodec_receive_frame(ctx, frame) >= 0) {
      if (p.decoded == 0) p.centreLuma = frame->data[0][(kH / 2) * frame->linesize[0] + kW / 2];
      ++p.decoded;
    }
  };
  while (av_read_frame(fmt, pkt) >= 0) {
    if (pkt->stream_index == si) {
      ++p.packets;
      avcodec_send_packet(ctx, pkt);
      drain();
    }
    av_packet_unref(pkt);
  }
  avcodec_send_packet(ctx, nullptr);
  drain();
  av_frame_free(&frame);
  av_packet_free(&pkt);
  avcodec_free_context(&ctx);
  avformat_close_input(&fmt);
  return p;
}

// top-level MP4 box types in file order
std::vector<std::string> topLevelBoxes(const std::vector<char>& b) {
  std::vector<std::string> boxes;
  size_t pos = 0;
  while (pos + 8 <= b.size()) {
    std::uint64_t size = (std::uint64_t(std::uint8_t(b[pos])) << 24) |
                         (std::uint64_t(std::uint8_t(b[pos + 1])) << 16) |
                         (std::uint64_t(std::uint8_t(b[pos + 2])) << 8) | std::uint8_t(b[pos + 3]);
    boxes.emplace_back(&b[pos + 4], 4);
    if (size < 8) break;
    pos += size;
  }
  return boxes;
}

TEST(VideoEncoder, ThirtyFramesReadBackAsOneSecondOfTaggedH264) {
  const std::string path = tempPath("thirty.mp4");
  std::filesystem::remove(path);
  VideoEncoder enc;
  encode(smallOptions(path), 30, &enc);
  EXPECT_EQ(enc.codecName(), "libx264") << enc.notes();
  EXPECT_EQ(enc.framesEncoded(), 30);
  EXPECT_GT(enc.encodeSeconds(), 0.0);
  EXPECT_GT(enc.convertSeconds(), 0.0);
  ASSERT_TRUE(std::filesystem::exists(path));
  EXPECT_FALSE(std::filesystem::exists(path + ".partial"));
  const Probe p = probe(path);
  EXPECT_EQ(p.codec, AV_CODEC_ID_H264);
  EXPECT_EQ(p.packets, 30);
  EXPECT_EQ(p.decoded, 30);
  EXPECT_NEAR(p.streamSeconds, 1.0, 1e-9);
  EXPECT_NEAR(p.formatSeconds, 1.0, 1e-6);
  EXPECT_NEAR(p.fps, 30.0, 1e-9);
  EXPECT_EQ(p.pixFmt, AV_PIX_FMT_YUV420P);
  EXPECT_EQ(p.primaries, AVCOL_PRI_BT709);
  EXPECT_EQ(p.trc, AVCOL_TRC_BT709);
  EXPECT_EQ(p.space, AVCOL_SPC_BT709);
  EXPECT_EQ(p.range, AVCOL_RANGE_MPEG);
  // +faststart: the movie box comes before the media data
  const auto boxes = topLevelBoxes(fileBytes(path));
  const auto moov = std::find(boxes.begin(), boxes.end(), "moov");
  const auto mdat = std::find(boxes.begin(), boxes.end(), "mdat");
  ASSERT_NE(moov, boxes.end());
  ASSERT_NE(mdat, boxes.end());
  EXPECT_LT(moov - boxes.begin(), mdat - boxes.begin());
}

TEST(VideoEncoder, UsesTheBt709MatrixWithLimitedRange) {
  // flat (200, 60, 30): BT.709 Y = 16 + 219 (0.2126 R + 0.7152 G + 0.0722 B) / 255 = 91.2
  // (BT.601 would give 100.5)
  const std::string path = tempPath("flat.mp4");
  VideoEncoder::Options o = smallOptions(path);
  o.crf = 0;  // lossless: the decoded Y equals the converted Y
  VideoEncoder enc;
  enc.open(o);
  std::vector<std::uint8_t> flat(kW * kH * 3);
  for (size_t i = 0; i < flat.size(); i += 3) {
    flat[i] = 200;
    flat[i + 1] = 60;
    flat[i + 2] = 30;
  }
  for (int i = 0; i < 3; ++i) enc.push(flat);
  enc.close();
  const Probe p = probe(path);
  EXPECT_EQ(p.decoded, 3);
  EXPECT_NEAR(p.centreLuma, 91, 1);
}

TEST(VideoEncoder, ReproducibleModeGivesIdenticalBytes) {
  const std::string a = tempPath("repro_a.mp4"), b = tempPath("repro_b.mp4");
  VideoEncoder::Options o = smallOptions(a);
  o.queueCapacity = 1;  // a full queue must only slow push(), never lose frames
  encode(o, 30);
  o.path = b;
  o.queueCapacity = 8;
  encode(o, 30);
  const auto ba = fileBytes(a), bb = fileBytes(b);
  ASSERT_GT(ba.size(), 1000u);
  EXPECT_EQ(ba, bb);
  EXPECT_EQ(probe(a).packets, 30);
}

// deferred: the frames kept raw in one file as they come, none encoded before close(), which
// encodes them all: the same bytes as encoding them as they come, and the raw file removed
TEST(VideoEncoder, DeferredModeKeepsTheFramesRawAndGivesTheSameBytes) {
  const std::string live = tempPath("deferred_live.mp4"), later = tempPath("deferred.mp4");
  encode(smallOptions(live), 40);
  VideoEncoder::Options o = smallOptions(later);
  o.deferred = true;
  VideoEncoder enc;
  enc.open(o);
  EXPECT_EQ(enc.spoolPath(), later + ".frames.partial");
  for (int i = 0; i < 40; ++i) enc.push(frameAt(i));
  for (int wait = 0; wait < 1000 && enc.framesSpooled() < 40; ++wait)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_EQ(enc.framesSpooled(), 40);
  EXPECT_EQ(enc.framesEncoded(), 0);
  const std::vector<char> raw = fileBytes(enc.spoolPath());  // frame after frame, as pushed
  ASSERT_EQ(raw.size(), 40u * kW * kH * 3);
  const std::vector<std::uint8_t> last = frameAt(39);
  EXPECT_TRUE(std::equal(last.begin(), last.end(),
                         reinterpret_cast<const std::uint8_t*>(raw.data()) + 39 * kW * kH * 3));
  enc.close();
  EXPECT_EQ(enc.framesEncoded(), 40);
  EXPECT_FALSE(std::filesystem::exists(later + ".frames.partial"));
  EXPECT_FALSE(std::filesystem::exists(later + ".partial"));
  EXPECT_EQ(fileBytes(later), fileBytes(live));
  EXPECT_EQ(probe(later).decoded, 40);
}

// the raw frames' file cannot be made (a folder has its name): open() fails naming it, and
// leaves neither the video's partial file nor that folder's contents changed
TEST(VideoEncoder, DeferredModeThatCannotKeepItsFramesFailsAtOpen) {
  const std::string path = tempPath("deferred_blocked.mp4");
  std::filesystem::remove(path + ".partial");
  std::filesystem::create_directories(path + ".frames.partial");
  VideoEncoder::Options o = smallOptions(path);
  o.deferred = true;
  VideoEncoder enc;
  try {
    enc.open(o);
    ADD_FAILURE() << "open() succeeded";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("video: cannot create '" + path +
                                         ".frames.partial' (the frames kept until the end, "
                                         "output.encode: after): Is a directory"),
              std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(enc.isOpen());
  EXPECT_FALSE(std::filesystem::exists(path + ".partial"));
  EXPECT_TRUE(std::filesystem::is_directory(path + ".frames.partial"));
  std::filesystem::remove(path + ".frames.partial");
}

TEST(VideoEncoder, MissingEncoderFailsClearlyOrFallsBack) {
  const std::string path = tempPath("fallback.mp4");
  VideoEncoder::Options o = smallOptions(path);
  o.codec = "libnosuchencoder";
  o.allowFallback = false;
  VideoEncoder strict;
  try {
    strict.open(o);
    FAIL() << "expected esim::Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("'libnosuchencoder' is not available"), std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(strict.isOpen());
  o.allowFallback = true;
  VideoEncoder enc;
  encode(o, 10, &enc);
  EXPECT_TRUE(enc.codecName() == "libopenh264" || enc.codecName() == "mpeg4") << enc.codecName();
  EXPECT_NE(enc.notes().find("falling back"), std::string::npos);
  const Probe p = probe(path);
  EXPECT_EQ(p.decoded, 10);
  EXPECT_NEAR(p.streamSeconds, 10.0 / 30.0, 1e-9);
}

TEST(VideoEncoder, PartialFileWhileOpenAndBadInput) {
  const std::string path = tempPath("partial.mp4");
  std::filesystem::remove(path);
  VideoEncoder enc;
  enc.open(smallOptions(path));
  enc.push(frameAt(0));
  EXPECT_TRUE(std::filesystem::exists(path + ".partial"));
  EXPECT_FALSE(std::filesystem::exists(path));
  EXPECT_THROW(enc.push(std::vector<std::uint8_t>(10)), Error);  // wrong size
  enc.close();
  EXPECT_TRUE(std::filesystem::exists(path));
  EXPECT_FALSE(std::filesystem::exists(path + ".partial"));

  VideoEncoder::Options odd = smallOptions(tempPath("odd.mp4"));
  odd.width = 161;
  EXPECT_THROW(VideoEncoder().open(odd), Error);
  VideoEncoder::Options nodir = smallOptions("/nonexistent-dir/x/video.mp4");
  VideoEncoder bad;
  EXPECT_THROW(bad.open(nodir), Error);
  EXPECT_FALSE(std::filesystem::exists("/nonexistent-dir/x/video.mp4.partial"));
  VideoEncoder::Options preset = smallOptions(tempPath("preset.mp4"));
  preset.preset = "warp9";
  EXPECT_THROW(VideoEncoder().open(preset), Error);
  EXPECT_FALSE(std::filesystem::exists(preset.path + ".partial"));
}

// while the video grows, its partial file is a fragmented MP4 that plays up to its last
// fragment (a fragment from each key frame, every 2 s): what a killed process leaves is
// readable. close() rewrites it as one regular MP4 (index in front) of every frame.
TEST(VideoEncoder, ThePartialFilePlaysUpToItsLastFragment) {
  const std::string path = tempPath("growing.mp4");
  std::filesystem::remove(path);
  VideoEncoder enc;
  enc.open(smallOptions(path));
  for (int i = 0; i < 130; ++i) enc.push(frameAt(i));
  for (int wait = 0; wait < 1000 && enc.framesEncoded() < 130; ++wait)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_EQ(enc.framesEncoded(), 130);
  const Probe growing = probe(path + ".partial");
  EXPECT_EQ(growing.codec, AV_CODEC_ID_H264);
  EXPECT_GE(growing.decoded, 60);  // frames 0-59, and 60-119 once key frame 120 is out
  EXPECT_LE(growing.decoded, 120);
  EXPECT_EQ(growing.decoded % 60, 0);
  EXPECT_EQ(topLevelBoxes(fileBytes(path + ".partial")).at(1), "moov");  // empty, in front
  enc.close();
  const Probe done = probe(path);
  EXPECT_EQ(done.decoded, 130);
  EXPECT_NEAR(done.streamSeconds, 130 / 30.0, 1e-9);
  EXPECT_NEAR(done.formatSeconds, 130 / 30.0, 1e-3);  // (the movie header's ms)
  const auto boxes = topLevelBoxes(fileBytes(path));
  EXPECT_EQ(std::count(boxes.begin(), boxes.end(), "moof"), 0) << "one regular MP4";
  EXPECT_FALSE(std::filesystem::exists(path + ".partial"));
  EXPECT_FALSE(std::filesystem::exists(path + ".regular.partial"));
}

// the rewrite as a regular MP4 cannot be written (a folder has its name, standing for a
// disk that fills): close() fails saying so, and the fragmented file, complete, stays and
// plays every frame; the folder, not the encoder's, stays too
TEST(VideoEncoder, AFailedRewriteKeepsTheFragmentedVideo) {
  const std::string path = tempPath("rewrite_fails.mp4");
  std::filesystem::remove(path);
  std::filesystem::remove(path + ".partial");
  std::filesystem::create_directories(path + ".regular.partial");
  VideoEncoder enc;
  enc.open(smallOptions(path));
  for (int i = 0; i < 30; ++i) enc.push(frameAt(i));
  try {
    enc.close();
    ADD_FAILURE() << "close() succeeded";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("; every frame is kept in '" + path +
                                         ".partial' (a fragmented MP4, which plays)"),
              std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(path));
  EXPECT_EQ(probe(path + ".partial").decoded, 30);
  EXPECT_TRUE(std::filesystem::is_directory(path + ".regular.partial"));
  std::filesystem::remove(path + ".partial");
  std::filesystem::remove(path + ".regular.partial");
}

TEST(VideoEncoder, DestructorFinishesAnOpenVideo) {
  const std::string path = tempPath("dtor.mp4");
  std::filesystem::remove(path);
  {
    VideoEncoder enc;
    enc.open(smallOptions(path));
    for (int i = 0; i < 5; ++i) enc.push(frameAt(i));
  }
  const Probe p = probe(path);
  EXPECT_EQ(p.decoded, 5);
  EXPECT_FALSE(VideoEncoder::libraryVersions().empty());
}

}  // namespace
}  // namespace esim
