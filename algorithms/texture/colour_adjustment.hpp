// Global colour adjustment between the colour cameras of a texture (rgbd-texture,
// docs/algorithms.md "Texturing"): one gain and one offset per camera and channel, so that the
// cameras agree where they see the same surface. The observations are surface points (face
// centres) seen by two or more cameras; for each pair of cameras (a, b) seeing a point with
// colours c_a, c_b the residual is (g_a c_a + o_a) - (g_b c_b + o_b); a weak prior pulls every
// gain to 1 and every offset to 0, and the gauge is fixed by constraints: the mean gain is 1 and
// the mean offset 0 (else the pairwise terms would shrink all gains together). Linear least
// squares with two equality constraints, solved per channel through its KKT system. The global step
// of Waechter et al., ECCV 2014 §3.2, reduced to an affine model per camera (their per-vertex
// levelling is not done here).
#pragma once

#include <Eigen/Core>
#include <vector>

#include "algorithms/texture/view_selection.hpp"
#include "toolkit/report.hpp"

namespace rgbd::texture {

/// c' = gain * c + offset per channel (BGR order, as the images), colours in [0, 255].
struct ColourGain {
    Eigen::Vector3d gain = Eigen::Vector3d::Ones();
    Eigen::Vector3d offset = Eigen::Vector3d::Zero();  ///< in colour levels (0-255)
};

struct AdjustOptions {
    bool enabled = true;  ///< false: every gain 1, every offset 0
    /// Weight of the prior (g - 1)^2 + (o / 255)^2 per camera, relative to the mean number of
    /// observation pairs per camera (colours scaled to [0, 1] in the residuals).
    double prior_weight = 0.05;
    /// Pairs whose colours differ by more than this (levels, any channel) are left out: an
    /// occlusion the depth test missed, a specular highlight.
    double outlier_levels = 60.0;
    std::size_t max_points = 40000;  ///< surface points used at most (evenly spaced faces)

    void check() const;
};

/// Solves for the per-view gains and offsets. `scene` and `quality` as from face_quality;
/// report gets the number of points and pairs and each view's gains and offsets (RGB order).
std::vector<ColourGain> adjust_colours(const render::RenderScene& scene,
                                       const std::vector<TextureView>& views,
                                       const FaceQuality& quality, const AdjustOptions& options,
                                       Report& report);

/// Applies `gain` to a BGR image (saturating).
void apply_gain(cv::Mat& bgr, const ColourGain& gain);

/// Bilinear BGR colour (levels) of a CV_8UC3 image at pixel coordinates (u, v) (pixel centres at
/// integers; clamped to the image).
Eigen::Vector3d sample_bgr(const cv::Mat& bgr, double u, double v);

/// `gain` applied to one BGR colour, clamped to [0, 255] (as apply_gain, without rounding).
inline Eigen::Vector3d adjusted(const ColourGain& gain, const Eigen::Vector3d& bgr) {
    return (gain.gain.cwiseProduct(bgr) + gain.offset).cwiseMax(0.0).cwiseMin(255.0);
}

}  // namespace rgbd::texture
