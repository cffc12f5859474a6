// Sensor noise for synthetic RGB-D captures: axial depth noise sigma_z(z, theta), lateral
// jitter at depth edges, ToF flying pixels, grazing and random dropouts, random outliers,
// quantisation, and colour noise; with a per-pixel label image saying what happened to each
// pixel. Every draw comes from a counter-based generator addressed by the pixel, so results
// depend only on the seed. Sources: docs/algorithms.md, synthetic ground truth and §4 (Kinect v2
// model recalled from Fankhauser et al., ICAR 2015), the README of the team's test data
// ("Recommendation: simulating a multi-sensor rig"). See also: rasterizer.hpp, synthesize.hpp.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>

#include "toolkit/camera.hpp"
#include "validation/synth/rasterizer.hpp"

namespace rgbd::synth {

/// Per-pixel labels written to gt/<sensor>/labels/ (docs/formats.md).
enum class PixelLabel : std::uint8_t {
    kNoReturn = 0,  ///< nothing hit, or the depth is outside the sensor range
    kSurface = 1,   ///< a measurement of the surface (with axial noise)
    kFlying = 2,    ///< flying (mixed) pixel between foreground and background
    kOutlier = 3,   ///< random outlier, uniform in the frustum within the sensor range
    kDropout = 4,   ///< the surface was hit but the sensor returned nothing (grazing or random)
    kShadow = 5,    ///< structured-light shadow (not produced by the ToF model)
};

/// Depth noise model of a sensor type.
enum class DepthNoiseModel {
    kKinectV2,  ///< sigma_z [mm] = 1.5 - 0.5 z + 0.3 z^2 + 0.1 z^1.5 theta^2 / (pi/2 - theta)^2
    kSr300,     ///< sigma_z [mm] = 0.5 + 2 z^2 + 0.1 z^1.5 theta^2 / (pi/2 - theta)^2 (ours)
};

/// "kinect_v2" or "sr300" (the noise.model key of rig.json).
std::string to_string(DepthNoiseModel model);

/// Standard deviation of the axial noise, metres, at depth z_m and incidence angle theta_rad
/// (between the viewing ray and the surface normal; clamped below 89 degrees).
double sigma_z_m(DepthNoiseModel model, double z_m, double theta_rad);

/// The physical limits of a depth sensor that the noise needs.
struct DepthSensorTraits {
    DepthNoiseModel model = DepthNoiseModel::kKinectV2;
    double range_min_m = 0.5;  ///< nearer returns are invalid
    double range_max_m = 4.5;  ///< farther returns are invalid
    double quantum_m = 0.001;  ///< depth quantisation step (Kinect v2 1 mm, SR300 1/8 mm)
};

/// Which noise to inject; defaults are the noise of the peer comparisons. Written to gt/scene.json.
struct NoiseOptions {
    bool axial = true;                ///< Gaussian noise along the ray, sigma_z(z, theta)
    bool lateral = true;              ///< lateral jitter of pixels in the depth-edge band
    double lateral_sigma_px = 0.8;    ///< std of the lateral jitter, depth pixels
    bool flying = true;               ///< flying pixels in the discontinuity band
    double flying_fraction = 0.5;     ///< share of band pixels that become flying pixels
    double discontinuity_m = 0.03;    ///< neighbour depth jump that counts as a discontinuity
    bool void_background = true;      ///< "no return" behind a silhouette acts as a background
                                      ///< at the range maximum (a far wall); false: no flying
                                      ///< pixels against the void
    bool grazing = true;              ///< dropouts at grazing incidence
    double grazing_start_deg = 70.0;  ///< dropout probability 0 at this incidence angle ...
    double grazing_end_deg = 85.0;    ///< ... rising linearly to 1 at this one
    double dropout_rate = 0.005;      ///< random dropouts, share of surface pixels
    double outlier_rate = 0.005;      ///< random outliers, expected count as a share of the
                                      ///< surface pixels, placed at uniformly random pixels
    bool quantize = true;             ///< round depth to the sensor's quantum
    double color_sigma = 2.0;         ///< Gaussian colour noise, grey levels (0 = none)

    /// All noise off (clean depth is still clipped to the sensor range and quantised off).
    static NoiseOptions none();
    /// Throws InputError on negative rates, fractions outside [0, 1], bad angles.
    void check() const;
    nlohmann::json to_json() const;
};

/// Noisy depth and the label of every pixel.
struct NoisyDepth {
    cv::Mat depth;   ///< CV_32FC1 metres, NaN = invalid
    cv::Mat labels;  ///< CV_8UC1, PixelLabel values
};

/// Applies the depth noise to a clean render. `seed` selects the noise; the same seed gives
/// the same result for any number of threads. Clean depth outside the sensor range becomes
/// kNoReturn.
NoisyDepth apply_depth_noise(const DepthRender& clean, const PinholeIntrinsics& intrinsics,
                             const DepthSensorTraits& sensor, const NoiseOptions& options,
                             std::uint64_t seed);

/// Adds Gaussian noise of `sigma` grey levels to every channel of a CV_8UC3 image, in place.
void apply_color_noise(cv::Mat& bgr, double sigma, std::uint64_t seed);

}  // namespace rgbd::synth
