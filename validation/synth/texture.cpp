#include "validation/synth/texture.hpp"

#include <algorithm>
#include <cmath>

#include "toolkit/error.hpp"

namespace rgbd::synth {

void TextureOptions::check() const {
    RGBD_CHECK(std::isfinite(hue_period_m) && hue_period_m > 0, "texture hue period must be > 0");
    RGBD_CHECK(std::isfinite(hue_offset_deg), "texture hue offset must be finite");
    check_range("texture saturation", saturation, Range::closed(0, 1));
    check_range("texture value", value, Range::closed(0, 1));
    RGBD_CHECK(std::isfinite(checker_size_m) && checker_size_m >= 0,
               "texture checker size must be >= 0");
    check_range("texture checker_dark", checker_dark, Range::closed(0, 1));
}

nlohmann::json TextureOptions::to_json() const {
    return {{"kind", "hue_gradient_z_times_checker_3d"},
            {"frame", "object: metres, z up, origin at the bounding-box centre"},
            {"hue_period_m", hue_period_m},
            {"hue_offset_deg", hue_offset_deg},
            {"saturation", saturation},
            {"value", value},
            {"checker_size_m", checker_size_m},
            {"checker_dark", checker_dark},
            {"formula",
             "hue = hue_offset_deg + 360 z / hue_period_m; v = value * (checker_dark if "
             "floor(x/s)+floor(y/s)+floor(z/s) is odd); rgb = round(255 * hsv_to_rgb)"}};
}

Rgb texture_color(const Eigen::Vector3d& p, const TextureOptions& t) {
    double hue = std::fmod(t.hue_offset_deg + 360.0 * p.z() / t.hue_period_m, 360.0);
    if (hue < 0) hue += 360.0;
    double v = t.value;
    if (t.checker_size_m > 0) {
        const auto cell = [&](double x) {
            return static_cast<long long>(std::floor(x / t.checker_size_m));
        };
        if (((cell(p.x()) + cell(p.y()) + cell(p.z())) & 1LL) != 0) v *= t.checker_dark;
    }
    // HSV -> RGB.
    const double c = v * t.saturation;
    const double h6 = hue / 60.0;
    const double x = c * (1.0 - std::abs(std::fmod(h6, 2.0) - 1.0));
    // Per 60-degree sector (hue is in [0, 360]): the channel (r, g, b) that gets c, the one
    // that gets x; the third stays 0.
    constexpr int kChromaChannel[6] = {0, 1, 1, 2, 2, 0};
    constexpr int kRampChannel[6] = {1, 0, 2, 1, 0, 2};
    const int sector = std::min(static_cast<int>(h6), 5);
    double rgb[3] = {0, 0, 0};
    rgb[kChromaChannel[sector]] = c;
    rgb[kRampChannel[sector]] = x;
    const double m = v - c;
    const auto to8 = [m](double f) {
        return static_cast<std::uint8_t>(std::clamp(std::lround(255.0 * (f + m)), 0L, 255L));
    };
    return {to8(rgb[0]), to8(rgb[1]), to8(rgb[2])};
}

}  // namespace rgbd::synth
