// video_encoder.h - RGB24 frames to an H.264 MP4 through libavcodec/libavformat.
//
// Pipeline (all on the encoder's own thread, fed by a bounded queue):
//   RGB24 (full range) --swscale, BT.709 matrix--> YUV420P (limited range)
//   --libx264, CRF + preset--> MP4, fragmented while it grows (a fragment from each key
//   frame, every 2 s), rewritten by close() as one regular MP4 (movflags +faststart)
// Stream tags: BT.709 primaries, transfer and matrix, limited ("tv") range.
// Timing: codec time base 1/fps (the rate as a fraction), pts = frame index, every packet's
// duration is one frame, so N frames last exactly N/fps seconds (the last one included).
// Reproducible mode: one encoder thread, AV_CODEC_FLAG_BITEXACT, swscale
// SWS_BITEXACT and the muxer's AVFMT_FLAG_BITEXACT (no library version strings,
// no creation time), so the same frames give the same MP4 bytes on the same
// machine and library versions.
// Fallback when libx264 is missing from the FFmpeg build (Options::codec names
// the wanted encoder; allowFallback tries the next): libx264 -> libopenh264
// (H.264, bit rate from the frame size) -> mpeg4 (MPEG-4 Part 2, constant
// quantiser from crf); the choice and the reason are printed on stderr once and
// kept in notes(). With allowFallback = false a missing encoder is an error.
// Files: frames go to "<path>.partial", a fragmented MP4 that plays up to its last
// fragment if the process is killed; close() rewrites it as "<path>.regular.partial",
// renamed to <path>, and removes the fragmented file. On an error both are removed,
// except when only that rewrite failed: the fragmented file, complete, stays (the error
// says so).
// Deferred mode (Options::deferred): the thread writes each frame as it comes, raw (RGB24,
// width*height*3 bytes), to "<path>.frames.partial" and encodes none until close(), which then
// encodes them all in order (the same bytes in reproducible mode as encoding them as they
// come) and removes that file, on success and on error alike. The frames' loop then has the
// encoder's CPU free (esim run's output.encode: after), at the cost of that file's size on
// disk until close() and of the encoding's time at the end; a process killed before close()
// leaves no video, only that file.
// The destructor closes an open encoder.
// Logging: if libav's log level is still its default (info), open() lowers it to
// warnings, so libx264's per-file banner does not flood stderr.
// Ownership: push() takes the frame by value (moved into the queue).
// Threads: open/push/close from one thread; the encoder thread is private.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace esim {

// frame rates a video accepts [1/s]
constexpr double kMinVideoFps = 0.01;
constexpr double kMaxVideoFps = 240.0;

// throws Error naming time.fps when a video cannot have this rate [1/s]
void validateVideoRate(double fps);

class VideoEncoder {
 public:
  struct Options {
    std::string path;           // output .mp4
    int width = 0, height = 0;  // frame size [px], even (yuv420p)
    double fps = 30;  // frames per second, exact (stored as a fraction)                   // frames
                      // per second
    int crf = 20;     // x264 constant rate factor, 0..51 (lower = better)
    std::string preset = "veryfast";  // x264 preset (ultrafast .. placebo)
    bool reproducible = true;         // bitexact, one thread
    int queueCapacity = 8;            // frames waiting before push() blocks
    std::string codec = "libx264";    // wanted encoder
    bool allowFallback = true;        // try libopenh264, then mpeg4 if it is missing
    bool deferred = false;            // spool the frames raw, encode them in close()
  };

  VideoEncoder();
  ~VideoEncoder();
  VideoEncoder(const VideoEncoder&) = delete;
  VideoEncoder& operator=(const VideoEncoder&) = delete;

  // opens the encoder and the file, starts the thread; throws esim::Error
  void open(const Options& options);
  // queues one RGB24 frame (top row first, width*height*3 bytes); returns at
  // once unless the queue is full; rethrows an error of the encoder thread
  void push(std::vector<std::uint8_t> rgb);
  // drains the queue (deferred: encodes every frame spooled), flushes the encoder, finishes
  // the file and renames it; rethrows an error of the encoder thread (the partial file is then
  // removed)
  void close();

  bool isOpen() const { return thread_.joinable(); }
  int framesEncoded() const { return framesEncoded_.load(); }
  int framesSpooled() const { return framesSpooled_.load(); }  // deferred: written raw so far
  std::string spoolPath() const { return opt_.path + ".frames.partial"; }
  double encodeSeconds() const { return encodeNs_.load() * 1e-9; }      // encoder + muxer time
  double convertSeconds() const { return convertNs_.load() * 1e-9; }    // RGB -> YUV time
  double pushWaitSeconds() const { return pushWaitNs_.load() * 1e-9; }  // push() blocked
  const std::string& codecName() const { return codecName_; }           // encoder in use
  const std::string& notes() const { return notes_; }                   // fallback message

  // "libavcodec 59.37.100, libavformat 59.27.100, libswscale 6.7.100"
  static std::string libraryVersions();

 private:
  struct Av;  // libav state (kept out of the header)
  void run();
  void convertAndEncode(const std::vector<std::uint8_t>& rgb);
  void encodeFrame(bool flush);
  void fail();

  Options opt_;
  std::unique_ptr<Av> av_;
  std::thread thread_;
  std::mutex mutex_;
  std::condition_variable notEmpty_, notFull_;
  std::deque<std::vector<std::uint8_t>> queue_;
  bool closing_ = false;
  std::exception_ptr error_;
  std::atomic<std::int64_t> encodeNs_{0}, convertNs_{0}, pushWaitNs_{0};
  std::atomic<int> framesEncoded_{0}, framesSpooled_{0};
  std::FILE* spool_ = nullptr;  // deferred: the raw frames, written by the thread
  std::string codecName_, notes_, tmpPath_;
};

}  // namespace esim
