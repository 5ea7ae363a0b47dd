// image_png.h - PNG files of RGB24 frames through libavcodec's PNG codec.
//
// No extra dependency: FFmpeg's PNG encoder/decoder (lossless, 8 bits per
// channel). writePng writes to "<path>.tmp" and renames when complete.
// Images are RGB24, top row first, width*height*3 bytes.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace esim {

// writes the image; throws esim::Error naming the path on failure
void writePng(const std::string& path, const std::vector<std::uint8_t>& rgb, int width, int height);

struct RgbImage {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  // RGB24, top row first
};

// reads a PNG (any pixel format libavcodec decodes, converted to RGB24);
// throws esim::Error naming the path on failure
RgbImage readPng(const std::string& path);

}  // namespace esim
