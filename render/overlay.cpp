// overlay.cpp - colour bar and time text on the CPU (see overlay.h).
#include "render/overlay.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "render/bitmap_font.h"
#include "render/colormap.h"

namespace esim::render_detail {
namespace {

const std::array<std::uint8_t, 3> kTextColor{236, 236, 236};
const std::array<std::uint8_t, 3> kFrameColor{200, 200, 200};  // bar frame and ticks

// the colour bar at the right edge: frame, colours, unit, ticks and labels
void drawColorBar(std::vector<std::uint8_t>& frame, const RenderOptions& opt, int scale,
                  int margin) {
  const int w = opt.width, h = opt.height;
  const bool potential = opt.look == "potential";
  // vertical bar at the right: hot (high potential) at the top, ticks and labels to its left
  const ColormapLut& lut = colormapLut(opt.colormap);
  const int barW = std::max(4, h / 36);
  const int barH = static_cast<int>(std::lround(0.55 * h));
  const int barX = w - margin - barW;
  const int barY = (h - barH) / 2 + scale * kFontCellH / 2;
  fillRect(frame, w, h, barX - 1, barY - 1, barW + 2, barH + 2, kFrameColor);
  for (int y = 0; y < barH; ++y) {
    const double t = 1.0 - static_cast<double>(y) / (barH - 1);
    const auto& c = lut[static_cast<int>(std::lround(t * 255.0))];
    fillRect(frame, w, h, barX, barY + y, barW, 1, c);
  }
  const std::string unit = potential ? "V"
                                     : "\xC2\xB0"
                                       "C";
  drawText(frame, w, h, barX + barW / 2 - textWidthPx(unit, scale) / 2,
           barY - 1 - (kFontCellH + 1) * scale, unit, scale, kTextColor);
  const double lo = potential ? opt.vMinV : opt.tMinC, hi = potential ? opt.vMaxV : opt.tMaxC;
  const int tickLen = std::max(3, barW / 2);
  for (const ColorBarTick& tick : colorBarTicks(lo, hi, potential && opt.potentialLogScale)) {
    const int y = barY + static_cast<int>(std::lround((1.0 - tick.t) * (barH - 1)));
    fillRect(frame, w, h, barX - 1 - tickLen, y - scale / 2, tickLen, std::max(1, scale / 2 + 1),
             kFrameColor);
    const std::string label = formatNumber(tick.value, tick.step);
    drawText(frame, w, h, barX - 1 - tickLen - scale * 2 - textWidthPx(label, scale),
             y - (7 * scale) / 2, label, scale, kTextColor);
  }
}

}  // namespace

void fillRect(std::vector<std::uint8_t>& rgb, int w, int h, int x0, int y0, int rw, int rh,
              std::array<std::uint8_t, 3> c) {
  for (int y = std::max(0, y0); y < std::min(h, y0 + rh); ++y)
    for (int x = std::max(0, x0); x < std::min(w, x0 + rw); ++x)
      std::memcpy(&rgb[(static_cast<size_t>(y) * w + x) * 3], c.data(), 3);
}

double niceStep(double range) {
  const double raw = range / 5.0;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0})
    if (m * p >= raw * 0.75) return m * p;
  return 10 * p;
}

std::string formatNumber(double v, double step) {
  char buf[32];
  const int decimals = step >= 1 ? 0 : static_cast<int>(std::ceil(-std::log10(step) - 1e-9));
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v == 0 ? 0.0 : v);  // no "-0"
  return buf;
}

std::vector<ColorBarTick> colorBarTicks(double lo, double hi, bool logScale) {
  std::vector<ColorBarTick> out;
  if (logScale) {
    // logarithmic bar: ticks at {1, 2, 5} x 10^k, only 10^k when that gives more than 7
    const double logSpan = std::log(hi / lo);
    for (const bool decadesOnly : {false, true}) {
      std::vector<std::array<double, 2>> ticks;  // value, power of ten
      for (int k = static_cast<int>(std::floor(std::log10(lo))) - 1;
           k <= static_cast<int>(std::ceil(std::log10(hi))); ++k)
        for (double mant : {1.0, 2.0, 5.0}) {
          if (decadesOnly && mant != 1.0) continue;
          const double v = mant * std::pow(10.0, k);
          if (v >= lo * (1 - 1e-9) && v <= hi * (1 + 1e-9)) ticks.push_back({v, std::pow(10.0, k)});
        }
      if (ticks.size() > 7 && !decadesOnly) continue;
      for (const auto& [v, p] : ticks) out.push_back({v, std::log(v / lo) / logSpan, p});
      break;
    }
    return out;
  }
  const double step = niceStep(hi - lo);
  for (double v = std::ceil(lo / step - 1e-9) * step; v <= hi + 1e-9 * step; v += step)
    out.push_back({v, (v - lo) / (hi - lo), step});
  return out;
}

void drawOverlay(std::vector<std::uint8_t>& frame, const RenderOptions& opt, double timeS) {
  const int w = opt.width, h = opt.height;
  const int scale = std::max(1, static_cast<int>(std::lround(h / 240.0)));
  const int margin = std::max(4, h / 30);
  if (opt.showTime) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "t = %.2f s", timeS);
    drawText(frame, w, h, margin, margin, buf, scale, kTextColor);
  }
  if (opt.look == "tissue" || !opt.showColorBar) return;
  drawColorBar(frame, opt, scale, margin);
}

}  // namespace esim::render_detail
