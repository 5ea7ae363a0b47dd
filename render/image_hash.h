// image_hash.h - exact and perceptual hashes of RGB24 frames, tolerant comparison.
//
// Exact: xxh3-64 (XXH3_64bits, seed 0) of the raw RGB bytes, before any colour
// conversion. A run's "all frames" hash is xxh3-64 over the sequence of frame
// hashes, each as 8 little-endian bytes (FrameHashSequence).
// Perceptual: dHash-64. The image is reduced to luma Y = (77 R + 150 G + 29 B)/256,
// box-averaged onto a 9 x 8 grid; bit (8*r + c) is 1 when cell (r, c) is
// brighter than cell (r, c+1). Near-identical images differ in few bits
// (hammingDistance); unrelated ones in ~32.
// Tolerant comparison (compareImages), over all channels:
//   PSNR = 10 log10(255^2 / MSE) dB (infinite when identical),
//   offShare = share of pixels whose largest channel difference exceeds
//              kPixelDiffThreshold = 16 (of 255).
// Thresholds and why: software (llvmpipe) and GPU drivers differ by 1-3 levels in
// interpolation and rounding, and by whole pixels along triangle edges where the
// rasterisation rules or MSAA sample patterns differ. A 16-level step (6%) is
// about the smallest change a viewer notices in a flat colour, so rounding noise
// stays below it while a changed colour map, lighting or geometry crosses it.
// kMinPsnrDb = 40 dB (RMS error 2.6 levels) and kMaxOffShare = 0.5% (edge pixels
// of a 1280x720 frame are ~1-2%; a moved edge only touches a part of them) are
// the default pass limits of imagesMatch().
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace esim {

constexpr int kPixelDiffThreshold = 16;  // max channel difference counted as "off" [0..255]
constexpr double kMinPsnrDb = 40.0;      // pass limit for PSNR [dB]
constexpr double kMaxOffShare = 0.005;   // pass limit for the share of off pixels

// xxh3-64 of the bytes
std::uint64_t hashBytes(const std::uint8_t* data, size_t size);
inline std::uint64_t hashFrame(const std::vector<std::uint8_t>& rgb) {
  return hashBytes(rgb.data(), rgb.size());
}

// the per-frame hashes of a run and the hash over all of them
class FrameHashSequence {
 public:
  void add(std::uint64_t frameHash) { hashes_.push_back(frameHash); }
  const std::vector<std::uint64_t>& frameHashes() const { return hashes_; }
  std::uint64_t combined() const;  // xxh3-64 of the hashes as little-endian bytes

 private:
  std::vector<std::uint64_t> hashes_;
};

// 64-bit difference hash of an RGB24 image (see above); throws on a bad size
std::uint64_t perceptualHash(const std::vector<std::uint8_t>& rgb, int width, int height);

// number of differing bits
int hammingDistance(std::uint64_t a, std::uint64_t b);

// 16 lowercase hex digits
std::string hashToHex(std::uint64_t h);

struct ImageComparison {
  double psnrDb = 0;    // +inf when identical
  double offShare = 0;  // share of pixels off by more than the threshold [0,1]
  int maxDiff = 0;      // largest channel difference [0..255]
  long offPixels = 0;   // number of such pixels
};

// compares two RGB24 images of equal size; throws esim::Error on size mismatch
ImageComparison compareImages(const std::vector<std::uint8_t>& a,
                              const std::vector<std::uint8_t>& b, int width, int height,
                              int threshold = kPixelDiffThreshold);

// true when psnr >= minPsnrDb and offShare <= maxOffShare
bool imagesMatch(const ImageComparison& c, double minPsnrDb = kMinPsnrDb,
                 double maxOffShare = kMaxOffShare);

// diff image (RGB24): image a darkened to a quarter grey, pixels off by more
// than the threshold in red (brightness grows with the difference), smaller
// non-zero differences in blue
std::vector<std::uint8_t> diffImage(const std::vector<std::uint8_t>& a,
                                    const std::vector<std::uint8_t>& b, int width, int height,
                                    int threshold = kPixelDiffThreshold);

}  // namespace esim
