// Refinement of the colour cameras' poses against the mesh by photometric consistency
// (rgbd-texture --refine-colour, docs/algorithms.md "Texturing"), for depth-to-colour extrinsics
// (or frame poses) that are slightly off: the rigid part of Zhou and Koltun, "Color Map
// Optimization for 3D Reconstruction with Consumer Depth Cameras", SIGGRAPH 2014, §4-5 (without
// their non-rigid image warping). Points are sampled on the mesh's faces about one colour pixel
// apart; a point is visible in a camera when it passes the depth test of the view selection
// against the mesh rendered into that camera (algorithms/render/), faces the camera within
// acos(min_cos) and lies away from depth discontinuities of the rendering (where a small pose
// error swaps surface and background). Points seen by at least two cameras get a proxy colour
// C(p), the mean of the cameras' grey levels at their projections; the refinement alternates
// (a) C(p) and (b) one Gauss-Newton step per camera (in parallel) on its pose T, minimising
// sum_p rho(I(pi(T p)) - C(p)) with I the camera's slightly blurred grey image, its gradient
// from a Sobel filter, rho a Huber norm, and priors towards the initial pose: a Huber one, stiff
// near 0, that holds the motions of all cameras together which the photometric cost does not see
// (on a sphere: a common rotation about its centre), and a weak quadratic one against the drift
// of the weakly observed shift along the optical axis. It runs coarse to fine over an image pyramid
// (the basin of a 1-degree error is several pixels at full resolution) and stops at a level when no
// camera moves by more than 0.001 degree / 0.01 mm. A camera whose correction exceeds
// max_rotation_deg or max_translation_m, or whose residual does not decrease, keeps its original
// pose (refused, with the reason in the report); a camera with fewer than min_samples shared points
// is left alone. See also: view_selection.hpp (visibility), texture_mesh.hpp (the chain).
#pragma once

#include <vector>

#include "algorithms/render/rasterizer.hpp"
#include "algorithms/texture/view_selection.hpp"
#include "toolkit/pose.hpp"
#include "toolkit/report.hpp"

namespace rgbd::texture {

struct RefineOptions {
    bool enabled = false;
    int iterations = 50;  ///< most Gauss-Newton iterations per pyramid level
    int levels = 3;       ///< pyramid levels (1 = full resolution only)
    /// Points seen more obliquely than acos(min_cos) do not count for a camera.
    double min_cos = 0.4;
    double blur_px = 1.0;  ///< Gaussian sigma of the grey images before the Sobel filter, pixels
    /// Depth test against the rendered mesh (as SelectionOptions).
    double depth_tolerance_m = 0.004;
    double depth_tolerance_rel = 0.005;
    /// A point within `edge_px` pixels of a depth jump of more than `edge_jump_m` in the
    /// rendering does not count (at each level).
    int edge_px = 2;
    double edge_jump_m = 0.02;
    double huber = 0.05;  ///< Huber threshold on the residual, grey level / 255
    /// Quadratic prior towards the initial pose: a correction of 1 degree or 10 mm costs this
    /// many grey levels (RMS) at every point the camera sees.
    double prior_levels = 0.3;
    /// Corrections above these are refused: the camera keeps its pose.
    double max_rotation_deg = 3.0;
    double max_translation_m = 0.03;
    /// Point spacing on the mesh, metres; 0 = the median colour pixel's footprint on the mesh.
    double sample_spacing_m = 0;
    int max_samples = 400000;  ///< the spacing grows until the points are at most this many
    int min_samples = 200;     ///< cameras sharing fewer points with others are left alone

    /// Throws InputError for values out of range.
    void check() const;
};

/// The refined world_from_camera of every view (the original where refused or left alone).
/// Report: samples, spacing, per-level iterations, RMS photometric residual before and after
/// (grey levels 0-255, on the blurred grey images at full resolution, over all visible
/// (point, camera) pairs of points seen twice), per camera: status (refined, refused, unchanged),
/// reason, rotation (degrees) and camera-centre shift (mm) of the correction, its residuals
/// and the refined pose (3x4 row-major). Throws InputError when a view's image is missing or
/// not of its intrinsics' size.
std::vector<Pose> refine_colour_poses(const render::RenderScene& scene,
                                      const std::vector<TextureView>& views,
                                      const RefineOptions& options, Report& report);

}  // namespace rgbd::texture
