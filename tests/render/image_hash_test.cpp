// Tests for render/image_hash.cpp: xxh3 frame hashes, dHash, PSNR comparison, diff image.
#include "render/image_hash.h"

#include <gtest/gtest.h>
#include <xxhash.h>

#include <cmath>
#include <limits>

#include "sim/core_error.h"

namespace esim {
namespace {

constexpr int kW = 160, kH = 120;

// horizontal ramp: bright on the left, dark on the right
std::vector<std::uint8_t> ramp(bool brightLeft) {
  std::vector<std::uint8_t> img(kW * kH * 3);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      const int v = brightLeft ? 255 - x * 255 / (kW - 1) : x * 255 / (kW - 1);
      for (int k = 0; k < 3; ++k) img[(y * kW + x) * 3 + k] = static_cast<std::uint8_t>(v);
    }
  return img;
}

TEST(ImageHash, Xxh3KnownValueAndStreamingAgreement) {
  // XXH3-64 of the empty input with seed 0 (xxHash's published sanity value)
  EXPECT_EQ(hashBytes(nullptr, 0), 0x2D06800538D394C2ULL);
  // one-shot and streaming XXH3 agree on a frame (independent code paths)
  const auto img = ramp(true);
  XXH3_state_t* st = XXH3_createState();
  XXH3_64bits_reset(st);
  XXH3_64bits_update(st, img.data(), 1000);
  XXH3_64bits_update(st, img.data() + 1000, img.size() - 1000);
  EXPECT_EQ(hashFrame(img), XXH3_64bits_digest(st));
  XXH3_freeState(st);
  // any one-bit change changes the hash
  auto flipped = img;
  flipped[12345] ^= 1;
  EXPECT_NE(hashFrame(img), hashFrame(flipped));
  EXPECT_EQ(hashToHex(0x2D06800538D394C2ULL), "2d06800538d394c2");
}

TEST(ImageHash, SequenceHashIsOverLittleEndianFrameHashes) {
  FrameHashSequence seq;
  seq.add(0x0102030405060708ULL);
  seq.add(0xA0B0C0D0E0F00010ULL);
  const std::uint8_t bytes[16] = {0x08, 0x07, 0x06, 0x05, 0x04, 0x03, 0x02, 0x01,
                                  0x10, 0x00, 0xF0, 0xE0, 0xD0, 0xC0, 0xB0, 0xA0};
  EXPECT_EQ(seq.combined(), XXH3_64bits(bytes, 16));
  FrameHashSequence swapped;  // order matters
  swapped.add(0xA0B0C0D0E0F00010ULL);
  swapped.add(0x0102030405060708ULL);
  EXPECT_NE(seq.combined(), swapped.combined());
  EXPECT_EQ(FrameHashSequence().combined(), 0x2D06800538D394C2ULL);
}

TEST(ImageHash, PerceptualHashOfRampsAndNoise) {
  // bright-left ramp: every cell brighter than its right neighbour -> all bits set
  EXPECT_EQ(perceptualHash(ramp(true), kW, kH), ~std::uint64_t{0});
  EXPECT_EQ(perceptualHash(ramp(false), kW, kH), std::uint64_t{0});
  EXPECT_EQ(
      hammingDistance(perceptualHash(ramp(true), kW, kH), perceptualHash(ramp(false), kW, kH)), 64);
  // small noise (+-2 levels) on a textured image changes at most a few bits
  std::vector<std::uint8_t> tex(kW * kH * 3), noisy;
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x)
      for (int k = 0; k < 3; ++k)
        tex[(y * kW + x) * 3 + k] =
            static_cast<std::uint8_t>(128 + 100 * std::sin(0.07 * x) * std::cos(0.05 * y + k));
  noisy = tex;
  for (size_t i = 0; i < noisy.size(); ++i)
    noisy[i] =
        static_cast<std::uint8_t>(std::clamp<int>(noisy[i] + static_cast<int>(i % 5) - 2, 0, 255));
  EXPECT_LE(hammingDistance(perceptualHash(tex, kW, kH), perceptualHash(noisy, kW, kH)), 4);
  EXPECT_THROW(perceptualHash(tex, kW, kH + 1), Error);
}

TEST(ImageHash, CompareIdenticalIsInfinitePsnr) {
  const auto a = ramp(true);
  const ImageComparison c = compareImages(a, a, kW, kH);
  EXPECT_TRUE(std::isinf(c.psnrDb));
  EXPECT_EQ(c.offPixels, 0);
  EXPECT_EQ(c.maxDiff, 0);
  EXPECT_TRUE(imagesMatch(c));
}

TEST(ImageHash, CompareKnownPerturbations) {
  std::vector<std::uint8_t> a(kW * kH * 3, 100);
  // +10 on the red channel of every pixel: MSE = 100/3, PSNR = 10 log10(3 * 255^2 / 100)
  auto b = a;
  for (size_t i = 0; i < b.size(); i += 3) b[i] += 10;
  ImageComparison c = compareImages(a, b, kW, kH);
  EXPECT_NEAR(c.psnrDb, 10.0 * std::log10(3.0 * 255.0 * 255.0 / 100.0), 1e-9);  // 32.902 dB
  EXPECT_NEAR(c.psnrDb, 32.9020, 1e-3);
  EXPECT_EQ(c.offPixels, 0);  // 10 <= threshold 16
  EXPECT_EQ(c.maxDiff, 10);
  EXPECT_FALSE(imagesMatch(c));  // below 40 dB
  // +20 on green of the first quarter of the rows: same MSE, a quarter of the pixels off
  auto d = a;
  for (int y = 0; y < kH / 4; ++y)
    for (int x = 0; x < kW; ++x) d[(y * kW + x) * 3 + 1] += 20;
  c = compareImages(a, d, kW, kH);
  EXPECT_NEAR(c.psnrDb, 10.0 * std::log10(3.0 * 4.0 * 255.0 * 255.0 / 400.0), 1e-9);
  EXPECT_DOUBLE_EQ(c.offShare, 0.25);
  EXPECT_EQ(c.offPixels, kW * kH / 4);
  // one pixel off by 17 in a 160x120 image: PSNR 10 log10(3*19200*255^2/289) ~ 71.1 dB, passes
  auto e = a;
  e[0] += 17;
  c = compareImages(a, e, kW, kH);
  EXPECT_EQ(c.offPixels, 1);
  EXPECT_NEAR(c.psnrDb, 10.0 * std::log10(3.0 * kW * kH * 255.0 * 255.0 / 289.0), 1e-9);
  EXPECT_TRUE(imagesMatch(c));
  EXPECT_THROW(compareImages(a, std::vector<std::uint8_t>(10), kW, kH), Error);
}

TEST(ImageHash, DiffImageMarksOffPixelsRed) {
  std::vector<std::uint8_t> a(kW * kH * 3, 100);
  auto b = a;
  b[(10 * kW + 20) * 3 + 2] = 200;  // off by 100 at (20, 10)
  b[(50 * kW + 70) * 3 + 0] = 103;  // off by 3 at (70, 50)
  const auto d = diffImage(a, b, kW, kH);
  ASSERT_EQ(d.size(), a.size());
  const std::uint8_t* off = &d[(10 * kW + 20) * 3];
  EXPECT_EQ(off[0], 228);  // 128 + 100
  EXPECT_LT(off[1], 30);
  const std::uint8_t* small = &d[(50 * kW + 70) * 3];
  EXPECT_GT(small[2], small[0] + 50);  // blue: below threshold
  const std::uint8_t* same = &d[0];
  EXPECT_EQ(same[0], same[1]);
  EXPECT_EQ(same[1], same[2]);
  EXPECT_EQ(same[0], 100 / 4);  // grey of a, a quarter
}

}  // namespace
}  // namespace esim
