// colormap.h - perceptual colour maps (inferno, viridis) as 256-entry RGB tables.
//
// The tables come from the 6th-degree polynomial fits of matplotlib's maps
// (M. Zucker, CC0): c(t) = sum_k c_k t^k, t in [0,1], clamped to [0,1] per
// channel and rounded to 8 bits; the fit's error is below 1.5/255 per channel.
// Entry i is the colour at t = i/255. The renderer uploads exactly this table as
// a 1D texture and draws the colour bar from it, so bar and surface agree.
#pragma once

#include <array>
#include <cstdint>
#include <string>

namespace esim {

using ColormapLut = std::array<std::array<std::uint8_t, 3>, 256>;

// table of the named map ("inferno" or "viridis"); throws esim::Error otherwise
const ColormapLut& colormapLut(const std::string& name);

// colour at t in [0,1] (clamped), nearest of the 256 entries
std::array<std::uint8_t, 3> colormapColor(const std::string& name, double t);

}  // namespace esim
