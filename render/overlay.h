// overlay.h - the overlay drawn on the CPU over the read-back frame: the colour bar
// with its ticks and unit, and the simulated time text.
//
// The bar stands at the right edge, hot (high) at the top, with ticks at
// {1, 2, 5} x 10^k steps (linear) or at {1, 2, 5} x 10^k values (logarithmic
// potential scale; decades only when that gives more than 7), labelled in deg C
// (temperature look) or V (potential look); no bar for the tissue look. Text uses
// the built-in 5x7 font (bitmap_font.h). Pure CPU, hence identical on every backend.
// Units: image pixels (top row 0), temperatures in deg C, potentials in V, time in s.
// Ownership: draws into the caller's RGB24 image. Internal to render/: not used
// outside the renderer.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "render/renderer.h"

namespace esim::render_detail {

// one tick of the colour bar
struct ColorBarTick {
  double value;  // in the bar's unit (deg C or V)
  double t;      // position on the bar, 0 bottom (lo) .. 1 top (hi)
  double step;   // label precision: formatNumber(value, step)
};

// fills the rectangle [x0, x0 + rw) x [y0, y0 + rh) of an RGB24 image (w x h), clipped
void fillRect(std::vector<std::uint8_t>& rgb, int w, int h, int x0, int y0, int rw, int rh,
              std::array<std::uint8_t, 3> c);

// tick step from {1, 2, 5} x 10^k giving 3..7 ticks over the range
double niceStep(double range);

// v with as many decimals as step needs ("0" for -0)
std::string formatNumber(double v, double step);

// ticks of a bar from lo to hi, bottom first: linear, or logarithmic (needs lo > 0)
std::vector<ColorBarTick> colorBarTicks(double lo, double hi, bool logScale);

// draws the options' overlay (time text, colour bar) into an RGB24 frame of
// opt.width x opt.height, top row first; timeS is the simulated time [s]
void drawOverlay(std::vector<std::uint8_t>& frame, const RenderOptions& opt, double timeS);

}  // namespace esim::render_detail
