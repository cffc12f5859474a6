// Procedural solid texture of synthetic objects: the true colour of any surface point, as a
// function of the point in the object frame (metres, z up, origin at the bounding-box centre).
// A smooth hue gradient along the height times a 3D checker of a few centimetres, so that
// colour carries information at a finer scale than the depth pixels (docs/algorithms.md, synthetic
// ground truth, and §5). See also: rasterizer.hpp (colour rendering), synthesize.hpp
// (gt/scene.json).
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "toolkit/point_cloud.hpp"

namespace rgbd::synth {

/// Parameters of the solid texture (written to gt/scene.json under "texture").
struct TextureOptions {
    double hue_period_m = 0.5;     ///< height over which the hue turns once around the circle
    double hue_offset_deg = 0.0;   ///< hue at height z = 0 (object centre), degrees
    double saturation = 0.65;      ///< HSV saturation in [0, 1]
    double value = 0.95;           ///< HSV value of the bright checker cells, in [0, 1]
    double checker_size_m = 0.03;  ///< edge of the cubic checker cells (0 = no checker)
    double checker_dark = 0.55;    ///< brightness factor of the dark cells, in [0, 1]

    /// Throws InputError on non-finite or out-of-range values.
    void check() const;
    nlohmann::json to_json() const;
};

/// True (noise-free) colour of the surface point `p_object` (object frame, metres).
/// Pure function: safe to call from many threads.
Rgb texture_color(const Eigen::Vector3d& p_object, const TextureOptions& options = {});

}  // namespace rgbd::synth
