// The fill stage (docs/algorithms.md §9-§13) as one call, shared by rgbd-fill and rgbd-reconstruct
// so that the pipe and the one-command run add the same points: hole detection on the aligned
// views, small holes by one of the four mechanisms, then the head top and large holes by 3D
// inpainting.
#pragma once

#include <optional>
#include <vector>

#include "algorithms/holes/hole_detection.hpp"
#include "algorithms/holes/hole_filling.hpp"
#include "algorithms/holes/large_holes.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"

namespace rgbd::pipeline {

/// What the fill stage runs, and with which options (each struct checked by its owner).
struct FillStageOptions {
    holes::BoundaryOptions detect;
    holes::FillOptions fill;
    holes::InpaintOptions inpaint;
    bool detect_only = false;   ///< find holes, add no points
    bool mark = false;          ///< add boundary / boundary_probability to the input points
    bool large = true;          ///< §12 large holes
    bool head_top = true;       ///< §13 the head top
    bool ignore_poses = false;  ///< no visibility test (the vertical axis still uses the poses)
    bool debug_colors = false;  ///< colour added points by mechanism
    /// Measured points beyond this many are thinned (holes::thin_points) before detection and
    /// inpainting: five times the mesher's 60,000-point budget
    /// (reconstruction::ReconstructionOptions::max_points), so every hole the mesh can show is
    /// still found. 0 = never thin; `mark` never thins (each input point gets its own flag).
    std::size_t max_points = 300000;
};

/// Debug colour of an added point by mechanism (M1 red, M2 green, M3 blue, M4 yellow, large
/// holes magenta, head top cyan).
Rgb mechanism_color(holes::FillMechanism mechanism);

/// Runs the fill stage on `views` (aligned; sensor-frame views are moved with their pose, all
/// are taken together in the world frame). Only measured points take part: points flagged
/// synthetic (rgbd-upsample's, an earlier fill's) neither open nor close holes. With `options.mark`
/// the views get the boundary properties. Returns the added points as one new world-frame view
/// (sensor "rgbd-fill", id one above the largest of `views`, normals, colours, synthetic = 1,
/// fill_mechanism 1-6), or nullopt when nothing was added (detect-only, no hole filled, or fewer
/// than 4 points: then report["note"] says why). The report gets the detection, filling and
/// inpainting reports, loop_list, small_loops and points_added_total.
std::optional<PointCloud> fill_stage(const std::vector<PointCloud*>& views,
                                     const FillStageOptions& options, Report& report,
                                     const Progress& progress = {});

}  // namespace rgbd::pipeline
