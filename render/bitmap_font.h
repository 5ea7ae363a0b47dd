// bitmap_font.h - a tiny 5x7 pixel font drawn into RGB24 images (overlay text).
//
// Glyphs: digits, A-Z, most of a-z, and " .,:;-+=/%()°". An unknown character is
// drawn as an outlined box. Each glyph cell is 6x9 font pixels (1 column and 2
// rows of spacing); `scale` makes each font pixel scale x scale image pixels.
// Text is UTF-8; only '°' (U+00B0) is recognised beyond ASCII. Drawing clips at
// the image border. Pure CPU, hence identical on every backend.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace esim {

constexpr int kFontCellW = 6;  // font pixels per character advance
constexpr int kFontCellH = 9;  // font pixels per line

// width of the text in image pixels at the given scale
int textWidthPx(const std::string& text, int scale);

// draws text with its top-left corner at (x, y) [image pixels] into an RGB24
// image (top row first); a one-pixel dark shadow keeps it legible on any
// background when `shadow` is set
void drawText(std::vector<std::uint8_t>& rgb, int width, int height, int x, int y,
              const std::string& text, int scale, std::array<std::uint8_t, 3> color,
              bool shadow = true);

}  // namespace esim
