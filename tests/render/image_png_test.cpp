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

}  // namespace
}  // namespace esim
