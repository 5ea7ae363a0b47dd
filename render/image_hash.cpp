// image_hash.cpp - xxh3 frame hashes, dHash, PSNR comparison (see image_hash.h).
#include "render/image_hash.h"

#include <xxhash.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <limits>

#include "sim/core_error.h"

namespace esim {
namespace {

void checkSize(const std::vector<std::uint8_t>& rgb, int width, int height, const char* what) {
  ESIM_VERIFY(width > 0 && height > 0 &&
                  rgb.size() == static_cast<size_t>(width) * static_cast<size_t>(height) * 3,
              std::string(what) + ": image has " + std::to_string(rgb.size()) +
                  " bytes, expected " + std::to_string(width) + "x" + std::to_string(height) +
                  "x3 (RGB24)");
}

}  // namespace

std::uint64_t hashBytes(const std::uint8_t* data, size_t size) { return XXH3_64bits(data, size); }

std::uint64_t FrameHashSequence::combined() const {
  std::vector<std::uint8_t> bytes;
  bytes.reserve(hashes_.size() * 8);
  for (std::uint64_t h : hashes_)
    for (int k = 0; k < 8; ++k) bytes.push_back(static_cast<std::uint8_t>(h >> (8 * k)));
  return hashBytes(bytes.data(), bytes.size());
}

std::uint64_t perceptualHash(const std::vector<std::uint8_t>& rgb, int width, int height) {
  checkSize(rgb, width, height, "perceptualHash");
  // box average of luma onto 9 x 8 cells (integer sums: exact, order-independent)
  constexpr int kCols = 9, kRows = 8;
  double cell[kRows][kCols] = {};
  for (int r = 0; r < kRows; ++r) {
    const int y0 = r * height / kRows, y1 = std::max(y0 + 1, (r + 1) * height / kRows);
    for (int c = 0; c < kCols; ++c) {
      const int x0 = c * width / kCols, x1 = std::max(x0 + 1, (c + 1) * width / kCols);
      std::uint64_t sum = 0;
      for (int y = y0; y < std::min(y1, height); ++y)
        for (int x = x0; x < std::min(x1, width); ++x) {
          const std::uint8_t* p = &rgb[(static_cast<size_t>(y) * width + x) * 3];
          sum += 77u * p[0] + 150u * p[1] + 29u * p[2];
        }
      cell[r][c] =
          static_cast<double>(sum) / ((std::min(y1, height) - y0) * (std::min(x1, width) - x0));
    }
  }
  std::uint64_t h = 0;
  for (int r = 0; r < kRows; ++r)
    for (int c = 0; c < 8; ++c)
      if (cell[r][c] > cell[r][c + 1]) h |= std::uint64_t{1} << (8 * r + c);
  return h;
}

int hammingDistance(std::uint64_t a, std::uint64_t b) { return std::popcount(a ^ b); }

std::string hashToHex(std::uint64_t h) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

ImageComparison compareImages(const std::vector<std::uint8_t>& a,
                              const std::vector<std::uint8_t>& b, int width, int height,
                              int threshold) {
  checkSize(a, width, height, "compareImages (first image)");
  checkSize(b, width, height, "compareImages (second image)");
  ImageComparison c;
  std::uint64_t sq = 0;
  const size_t n = static_cast<size_t>(width) * height;
  for (size_t i = 0; i < n; ++i) {
    int m = 0;
    for (int k = 0; k < 3; ++k) {
      const int d = std::abs(static_cast<int>(a[3 * i + k]) - static_cast<int>(b[3 * i + k]));
      sq += static_cast<std::uint64_t>(d * d);
      m = std::max(m, d);
    }
    c.maxDiff = std::max(c.maxDiff, m);
    if (m > threshold) ++c.offPixels;
  }
  const double mse = static_cast<double>(sq) / (3.0 * static_cast<double>(n));
  c.psnrDb =
      sq == 0 ? std::numeric_limits<double>::infinity() : 10.0 * std::log10(255.0 * 255.0 / mse);
  c.offShare = static_cast<double>(c.offPixels) / static_cast<double>(n);
  return c;
}

bool imagesMatch(const ImageComparison& c, double minPsnrDb, double maxOffShare) {
  return c.psnrDb >= minPsnrDb && c.offShare <= maxOffShare;
}

std::vector<std::uint8_t> diffImage(const std::vector<std::uint8_t>& a,
                                    const std::vector<std::uint8_t>& b, int width, int height,
                                    int threshold) {
  checkSize(a, width, height, "diffImage (first image)");
  checkSize(b, width, height, "diffImage (second image)");
  std::vector<std::uint8_t> out(a.size());
  const size_t n = static_cast<size_t>(width) * height;
  for (size_t i = 0; i < n; ++i) {
    int m = 0;
    for (int k = 0; k < 3; ++k)
      m = std::max(m, std::abs(static_cast<int>(a[3 * i + k]) - static_cast<int>(b[3 * i + k])));
    const int grey = (77 * a[3 * i] + 150 * a[3 * i + 1] + 29 * a[3 * i + 2]) / 256 / 4;
    std::uint8_t* p = &out[3 * i];
    if (m > threshold) {
      p[0] = static_cast<std::uint8_t>(std::min(255, 128 + m));
      p[1] = p[2] = static_cast<std::uint8_t>(grey / 2);
    } else if (m > 0) {
      p[0] = p[1] = static_cast<std::uint8_t>(grey);
      p[2] = static_cast<std::uint8_t>(std::min(255, grey + 60 + 8 * m));
    } else {
      p[0] = p[1] = p[2] = static_cast<std::uint8_t>(grey);
    }
  }
  return out;
}

}  // namespace esim
