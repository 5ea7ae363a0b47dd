// bitmap_font.cpp - 5x7 glyph table and text drawing (see bitmap_font.h).
#include "render/bitmap_font.h"

#include <cstring>

namespace esim {
namespace {

struct Glyph {
  const char* key;       // UTF-8 character
  std::uint8_t rows[7];  // 5 bits per row, bit 4 = leftmost column
};

// clang-format off
constexpr Glyph kGlyphs[] = {
  {" ", {0, 0, 0, 0, 0, 0, 0}},
  {"0", {0b01110, 0b10001, 0b10011, 0b10101, 0b11001, 0b10001, 0b01110}},
  {"1", {0b00100, 0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110}},
  {"2", {0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b01000, 0b11111}},
  {"3", {0b11111, 0b00010, 0b00100, 0b00010, 0b00001, 0b10001, 0b01110}},
  {"4", {0b00010, 0b00110, 0b01010, 0b10010, 0b11111, 0b00010, 0b00010}},
  {"5", {0b11111, 0b10000, 0b11110, 0b00001, 0b00001, 0b10001, 0b01110}},
  {"6", {0b00110, 0b01000, 0b10000, 0b11110, 0b10001, 0b10001, 0b01110}},
  {"7", {0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b01000, 0b01000}},
  {"8", {0b01110, 0b10001, 0b10001, 0b01110, 0b10001, 0b10001, 0b01110}},
  {"9", {0b01110, 0b10001, 0b10001, 0b01111, 0b00001, 0b00010, 0b01100}},
  {".", {0, 0, 0, 0, 0, 0b01100, 0b01100}},
  {",", {0, 0, 0, 0, 0b01100, 0b00100, 0b01000}},
  {":", {0, 0b01100, 0b01100, 0, 0b01100, 0b01100, 0}},
  {";", {0, 0b01100, 0b01100, 0, 0b01100, 0b00100, 0b01000}},
  {"-", {0, 0, 0, 0b01110, 0, 0, 0}},
  {"+", {0, 0b00100, 0b00100, 0b11111, 0b00100, 0b00100, 0}},
  {"=", {0, 0, 0b11111, 0, 0b11111, 0, 0}},
  {"/", {0, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0}},
  {"%", {0b11000, 0b11001, 0b00010, 0b00100, 0b01000, 0b10011, 0b00011}},
  {"(", {0b00010, 0b00100, 0b01000, 0b01000, 0b01000, 0b00100, 0b00010}},
  {")", {0b01000, 0b00100, 0b00010, 0b00010, 0b00010, 0b00100, 0b01000}},
  {"\xC2\xB0", {0b01100, 0b10010, 0b10010, 0b01100, 0, 0, 0}},
  {"A", {0b01110, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001}},
  {"B", {0b11110, 0b10001, 0b10001, 0b11110, 0b10001, 0b10001, 0b11110}},
  {"C", {0b01110, 0b10001, 0b10000, 0b10000, 0b10000, 0b10001, 0b01110}},
  {"D", {0b11100, 0b10010, 0b10001, 0b10001, 0b10001, 0b10010, 0b11100}},
  {"E", {0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b11111}},
  {"F", {0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b10000}},
  {"G", {0b01110, 0b10001, 0b10000, 0b10111, 0b10001, 0b10001, 0b01111}},
  {"H", {0b10001, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001}},
  {"I", {0b01110, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110}},
  {"J", {0b00111, 0b00010, 0b00010, 0b00010, 0b00010, 0b10010, 0b01100}},
  {"K", {0b10001, 0b10010, 0b10100, 0b11000, 0b10100, 0b10010, 0b10001}},
  {"L", {0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b11111}},
  {"M", {0b10001, 0b11011, 0b10101, 0b10101, 0b10001, 0b10001, 0b10001}},
  {"N", {0b10001, 0b10001, 0b11001, 0b10101, 0b10011, 0b10001, 0b10001}},
  {"O", {0b01110, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110}},
  {"P", {0b11110, 0b10001, 0b10001, 0b11110, 0b10000, 0b10000, 0b10000}},
  {"Q", {0b01110, 0b10001, 0b10001, 0b10001, 0b10101, 0b10010, 0b01101}},
  {"R", {0b11110, 0b10001, 0b10001, 0b11110, 0b10100, 0b10010, 0b10001}},
  {"S", {0b01111, 0b10000, 0b10000, 0b01110, 0b00001, 0b00001, 0b11110}},
  {"T", {0b11111, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100}},
  {"U", {0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110}},
  {"V", {0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01010, 0b00100}},
  {"W", {0b10001, 0b10001, 0b10001, 0b10101, 0b10101, 0b10101, 0b01010}},
  {"X", {0b10001, 0b10001, 0b01010, 0b00100, 0b01010, 0b10001, 0b10001}},
  {"Y", {0b10001, 0b10001, 0b10001, 0b01010, 0b00100, 0b00100, 0b00100}},
  {"Z", {0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0b11111}},
  {"a", {0, 0, 0b01110, 0b00001, 0b01111, 0b10001, 0b01111}},
  {"b", {0b10000, 0b10000, 0b10110, 0b11001, 0b10001, 0b10001, 0b11110}},
  {"c", {0, 0, 0b01110, 0b10000, 0b10000, 0b10001, 0b01110}},
  {"d", {0b00001, 0b00001, 0b01101, 0b10011, 0b10001, 0b10001, 0b01111}},
  {"e", {0, 0, 0b01110, 0b10001, 0b11111, 0b10000, 0b01110}},
  {"f", {0b00110, 0b01001, 0b01000, 0b11100, 0b01000, 0b01000, 0b01000}},
  {"g", {0, 0b01111, 0b10001, 0b10001, 0b01111, 0b00001, 0b01110}},
  {"h", {0b10000, 0b10000, 0b10110, 0b11001, 0b10001, 0b10001, 0b10001}},
  {"i", {0b00100, 0, 0b01100, 0b00100, 0b00100, 0b00100, 0b01110}},
  {"k", {0b10000, 0b10000, 0b10010, 0b10100, 0b11000, 0b10100, 0b10010}},
  {"l", {0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110}},
  {"m", {0, 0, 0b11010, 0b10101, 0b10101, 0b10001, 0b10001}},
  {"n", {0, 0, 0b10110, 0b11001, 0b10001, 0b10001, 0b10001}},
  {"o", {0, 0, 0b01110, 0b10001, 0b10001, 0b10001, 0b01110}},
  {"p", {0, 0, 0b11110, 0b10001, 0b11110, 0b10000, 0b10000}},
  {"r", {0, 0, 0b10110, 0b11001, 0b10000, 0b10000, 0b10000}},
  {"s", {0, 0, 0b01110, 0b10000, 0b01110, 0b00001, 0b11110}},
  {"t", {0b01000, 0b01000, 0b11100, 0b01000, 0b01000, 0b01001, 0b00110}},
  {"u", {0, 0, 0b10001, 0b10001, 0b10001, 0b10011, 0b01101}},
  {"v", {0, 0, 0b10001, 0b10001, 0b10001, 0b01010, 0b00100}},
  {"w", {0, 0, 0b10001, 0b10001, 0b10101, 0b10101, 0b01010}},
  {"x", {0, 0, 0b10001, 0b01010, 0b00100, 0b01010, 0b10001}},
  {"y", {0, 0, 0b10001, 0b10001, 0b01111, 0b00001, 0b01110}},
};
constexpr Glyph kUnknown = {"?", {0b11111, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b11111}};
// clang-format on

// glyph for the UTF-8 character at text[i]; advances i past it
const Glyph& nextGlyph(const std::string& text, size_t& i) {
  const unsigned char lead = static_cast<unsigned char>(text[i]);
  size_t len = 1;
  if (lead >= 0xF0)
    len = 4;
  else if (lead >= 0xE0)
    len = 3;
  else if (lead >= 0xC0)
    len = 2;
  len = std::min(len, text.size() - i);
  for (const Glyph& g : kGlyphs) {
    if (std::strlen(g.key) == len && text.compare(i, len, g.key) == 0) {
      i += len;
      return g;
    }
  }
  i += len;
  return kUnknown;
}

int countChars(const std::string& text) {
  int n = 0;
  for (size_t i = 0; i < text.size();) {
    nextGlyph(text, i);
    ++n;
  }
  return n;
}

void fillRect(std::vector<std::uint8_t>& rgb, int width, int height, int x0, int y0, int w, int h,
              std::array<std::uint8_t, 3> c) {
  for (int y = std::max(0, y0); y < std::min(height, y0 + h); ++y)
    for (int x = std::max(0, x0); x < std::min(width, x0 + w); ++x) {
      std::uint8_t* p = &rgb[(static_cast<size_t>(y) * width + x) * 3];
      p[0] = c[0];
      p[1] = c[1];
      p[2] = c[2];
    }
}

void drawPass(std::vector<std::uint8_t>& rgb, int width, int height, int x, int y,
              const std::string& text, int scale, std::array<std::uint8_t, 3> color) {
  int penX = x;
  for (size_t i = 0; i < text.size();) {
    const Glyph& g = nextGlyph(text, i);
    for (int r = 0; r < 7; ++r)
      for (int c = 0; c < 5; ++c)
        if (g.rows[r] & (1u << (4 - c)))
          fillRect(rgb, width, height, penX + c * scale, y + r * scale, scale, scale, color);
    penX += kFontCellW * scale;
  }
}

}  // namespace

int textWidthPx(const std::string& text, int scale) {
  const int n = countChars(text);
  return n == 0 ? 0 : (n * kFontCellW - 1) * scale;
}

void drawText(std::vector<std::uint8_t>& rgb, int width, int height, int x, int y,
              const std::string& text, int scale, std::array<std::uint8_t, 3> color, bool shadow) {
  if (shadow) {
    const int off = std::max(1, scale / 2);
    drawPass(rgb, width, height, x + off, y + off, text, scale, {0, 0, 0});
  }
  drawPass(rgb, width, height, x, y, text, scale, color);
}

}  // namespace esim
