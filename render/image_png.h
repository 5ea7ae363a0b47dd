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

// One-channel images are written for speed (every frame of a labelled run): the "up" row
// filter and zlib level 3.

// writes a one-channel image (8-bit grey, e.g. class ids); throws esim::Error naming the path
void writePngGray8(const std::string& path, const std::vector<std::uint8_t>& values, int width,
                   int height);

// writes a one-channel 16-bit image (PNG stores it big-endian; e.g. depth units); throws
// esim::Error naming the path
void writePngGray16(const std::string& path, const std::vector<std::uint16_t>& values, int width,
                    int height);

struct RgbImage {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  // RGB24, top row first
};

// reads a PNG (any pixel format libavcodec decodes, converted to RGB24);
// throws esim::Error naming the path on failure
RgbImage readPng(const std::string& path);

struct GrayImage {
  int width = 0, height = 0;
  int bitDepth = 0;                   // 8 or 16
  std::vector<std::uint16_t> values;  // one per pixel, top row first
};

// reads an 8- or 16-bit grey PNG as stored (no conversion); throws esim::Error naming the
// path for another pixel format
GrayImage readPngGray(const std::string& path);

}  // namespace esim
