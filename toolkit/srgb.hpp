// The sRGB transfer function (IEC 61966-2-1) tabulated for 8-bit levels: what colour
// comparisons in CIELab (the fill's exemplar inpainting, the 3D video's fusion) start from.
#pragma once

#include <array>
#include <cmath>

namespace rgbd {

/// The linear intensity in [0, 1] of each 8-bit sRGB level (x <= 0.04045: x / 12.92; else
/// ((x + 0.055) / 1.055)^2.4, with x the level / 255), computed once.
inline const std::array<float, 256>& srgb_linear_table() {
    static const std::array<float, 256> table = [] {
        std::array<float, 256> t{};
        for (int i = 0; i < 256; ++i) {
            const double x = i / 255.0;
            t[i] =
                static_cast<float>(x <= 0.04045 ? x / 12.92 : std::pow((x + 0.055) / 1.055, 2.4));
        }
        return t;
    }();
    return table;
}

}  // namespace rgbd
