// colormap.cpp - polynomial inferno/viridis tables (see colormap.h).
#include "render/colormap.h"

#include <algorithm>
#include <cmath>

#include "sim/core_error.h"

namespace esim {
namespace {

using Coeffs = std::array<std::array<double, 3>, 7>;  // c0..c6 per channel

// matplotlib fits by Matt Zucker (shadertoy WlfXRN), CC0
constexpr Coeffs kInferno = {{{0.0002189403691192265, 0.001651004631001012, -0.01948089843709184},
                              {0.1065134194856116, 0.5639564367884091, 3.932712388889277},
                              {11.60249308247187, -3.972853965665698, -15.9423941062914},
                              {-41.70399613139459, 17.43639888205313, 44.35414519872813},
                              {77.162935699427, -33.40235894210092, -81.80730925738993},
                              {-71.31942824499214, 32.62606426397723, 73.20951985803202},
                              {25.13112622477341, -12.24266895238567, -23.07032500287172}}};
constexpr Coeffs kViridis = {{{0.2777273272234177, 0.005407344544966578, 0.3340998053353061},
                              {0.1050930431085774, 1.404613529898575, 1.384590162594685},
                              {-0.3308618287255563, 0.214847559468213, 0.09509516302823659},
                              {-4.634230498983486, -5.799100973351585, -19.33244095627987},
                              {6.228269936347081, 14.17993336680509, 56.69055260068105},
                              {4.776384997670288, -13.74514537774601, -65.35303263337234},
                              {-5.435455855934631, 4.645852612178535, 26.3124352495832}}};

ColormapLut buildLut(const Coeffs& c) {
  ColormapLut lut{};
  for (int i = 0; i < 256; ++i) {
    const double t = i / 255.0;
    for (int ch = 0; ch < 3; ++ch) {
      double v = 0;  // Horner
      for (int k = 6; k >= 0; --k) v = v * t + c[k][ch];
      lut[i][ch] = static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0, 1.0) * 255.0));
    }
  }
  return lut;
}

}  // namespace

const ColormapLut& colormapLut(const std::string& name) {
  static const ColormapLut inferno = buildLut(kInferno);
  static const ColormapLut viridis = buildLut(kViridis);
  if (name == "inferno") return inferno;
  if (name == "viridis") return viridis;
  throw Error("look.colormap: unknown colour map '" + name + "', expected 'inferno' or 'viridis'");
}

std::array<std::uint8_t, 3> colormapColor(const std::string& name, double t) {
  const double u = std::isfinite(t) ? std::clamp(t, 0.0, 1.0) : 0.0;
  return colormapLut(name)[static_cast<int>(std::lround(u * 255.0))];
}

}  // namespace esim
