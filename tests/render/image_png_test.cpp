// Tests for render/image_png.cpp: lossless round trip, stable bytes, errors.
#include "render/image_png.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "render/image_hash.h"
#include "sim/core_error.h"

namespace esim {
namespace {

TEST(ImagePng, RoundTripIsLosslessAndBytesAreStable) {
  const int w = 37, h = 21;  // odd sizes: no row padding assumptions
  std::vector<std::uint8_t> img(w * h * 3);
  for (size_t i = 0; i < img.size(); ++i) img[i] = static_cast<std::uint8_t>((i * 7919) % 251);
  const auto dir = std::filesystem::temp_directory_path() / "esim_png_test";
  std::filesystem::create_directories(dir);
  const std::string a = (dir / "a.png").string(), b = (dir / "b.png").string();
  writePng(a, img, w, h);
  writePng(b, img, w, h);
  EXPECT_FALSE(std::filesystem::exists(a + ".tmp"));
  const RgbImage back = readPng(a);
  EXPECT_EQ(back.width, w);
  EXPECT_EQ(back.height, h);
  EXPECT_EQ(hashFrame(back.rgb), hashFrame(img));
  std::ifstream fa(a, std::ios::binary), fb(b, std::ios::binary);
  const std::string sa((std::istreambuf_iterator<char>(fa)), std::istreambuf_iterator<char>());
  const std::string sb((std::istreambuf_iterator<char>(fb)), std::istreambuf_iterator<char>());
  EXPECT_EQ(sa, sb);
  EXPECT_EQ(sa.substr(1, 3), "PNG");
}

// one-channel images (label masks, depth) keep their values and bit depth
TEST(ImagePng, GrayRoundTripsKeepValuesAndBitDepth) {
  const int w = 29, h = 13;
  std::vector<std::uint8_t> g8(w * h);
  std::vector<std::uint16_t> g16(w * h);
  for (size_t i = 0; i < g8.size(); ++i) {
    g8[i] = static_cast<std::uint8_t>((i * 31) % 256);
    g16[i] = static_cast<std::uint16_t>((i * 40503) % 65536);  // high and low bytes differ
  }
  const auto dir = std::filesystem::temp_directory_path() / "esim_png_test";
  std::filesystem::create_directories(dir);
  const std::string a = (dir / "g8.png").string(), b = (dir / "g16.png").string();
  writePngGray8(a, g8, w, h);
  writePngGray16(b, g16, w, h);
  const GrayImage back8 = readPngGray(a), back16 = readPngGray(b);
  EXPECT_EQ(back8.bitDepth, 8);
  EXPECT_EQ(back16.bitDepth, 16);
  ASSERT_EQ(back8.width, w);
  ASSERT_EQ(back16.height, h);
  for (size_t i = 0; i < g8.size(); ++i) {
    ASSERT_EQ(back8.values[i], g8[i]) << i;
    ASSERT_EQ(back16.values[i], g16[i]) << i;
  }
  EXPECT_THROW(writePngGray8(a, g8, w + 1, h), Error);
  // an RGB PNG is not grey
  writePng((dir / "rgb.png").string(), std::vector<std::uint8_t>(w * h * 3, 7), w, h);
  EXPECT_THROW(readPngGray((dir / "rgb.png").string()), Error);
}

TEST(ImagePng, ErrorsNameThePath) {
  std::vector<std::uint8_t> img(4 * 4 * 3, 0);
  try {
    writePng("/nonexistent-dir/x.png", img, 4, 4);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent-dir/x.png"), std::string::npos);
  }
  EXPECT_THROW(writePng("/tmp/x.png", img, 5, 4), Error);
  EXPECT_THROW(readPng("/nonexistent-dir/y.png"), Error);
}

// a disk that fills: the PNG is not renamed cut short as whole, no temporary file is left,
// and the error is a run's (the frame loop keeps the frames before it); /dev/full stands for
// the disk (its writes fail with ENOSPC), reached through the temporary file's name
TEST(ImagePng, ADiskThatFillsLeavesNoFileAndFailsTheRun) {
  if (!std::filesystem::is_character_file("/dev/full")) GTEST_SKIP() << "no /dev/full here";
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / "esim_image_png_test_full";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::filesystem::path png = dir / "frame.png";
  std::filesystem::create_symlink("/dev/full", png.string() + ".tmp");
  std::vector<std::uint8_t> img(64 * 64 * 3);
  for (size_t i = 0; i < img.size(); ++i) img[i] = static_cast<std::uint8_t>(i * 7919 % 251);
  try {
    writePng(png.string(), img, 64, 64);
    FAIL() << "the write to a full disk succeeded";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Run);
    EXPECT_NE(std::string(e.what()).find("write failed (disk full?)"), std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(png));
  EXPECT_FALSE(std::filesystem::is_symlink(png.string() + ".tmp"));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace esim
