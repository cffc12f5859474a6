// Per-face view selection for texturing a mesh from calibrated colour images (rgbd-texture,
// docs/algorithms.md "Texturing"). Each face gets the colour camera that sees it best: the data
// term is its projected area in the image times the cosine of the viewing angle, times the
// local sharpness of the image (gradient magnitude relative to the image's mean) as in Waechter,
// Moehrle and Goesele, "Let there be color!", ECCV 2014 (§3.1, which uses the gradient
// magnitude integral); visibility is a depth test against the mesh itself, rendered with the
// z-buffer rasteriser of algorithms/render/ into every colour camera (parallel over views). The
// labelling then trades quality against a Potts smoothness term over face adjacency, so that
// charts are large: a Markov random field minimised by iterated conditional modes (Besag, "On
// the statistical analysis of dirty pictures", JRSS B 1986): a few deterministic sweeps from
// the best view per face, each face taking the label that minimises its own data cost plus the
// penalty for differing from its edge neighbours. ICM finds a local minimum, not the graph-cut
// optimum of Waechter et al.; it suffices to absorb small islands into their surroundings.
// See also: atlas.hpp (charts and texture atlas), colour_adjustment.hpp, texture_mesh.hpp.
#pragma once

#include <array>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "algorithms/render/rasterizer.hpp"
#include "toolkit/camera.hpp"
#include "toolkit/pose.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"

namespace rgbd::texture {

/// One calibrated colour image.
struct TextureView {
    cv::Mat image;                              ///< CV_8UC3, BGR, undistorted (pinhole)
    PinholeIntrinsics intrinsics;               ///< without distortion; size of `image`
    Pose world_from_camera = Pose::Identity();  ///< pose of the colour camera
    std::string name;                           ///< for messages: "<sensor> frame <index>"
};

/// Options of the view selection.
struct SelectionOptions {
    /// Faces seen more obliquely than acos(min_cos) (angle between the face normal and the ray
    /// to the camera) are not textured from that view.
    double min_cos = 0.15;
    /// Depth test: a face point is visible when it lies at most this far (metres) behind the
    /// rendered surface, plus `depth_tolerance_rel` times its depth.
    double depth_tolerance_m = 0.004;
    double depth_tolerance_rel = 0.005;
    /// Faces whose projection comes closer than this to the image border (pixels) are not
    /// textured from that view (room for the atlas padding and the bilinear lookup).
    int border_px = 3;
    /// Weigh the data term by the image's local sharpness (gradient magnitude at the face
    /// centre over the image's mean, clamped to [0.5, 2]).
    bool sharpness = true;
    /// Potts weight of the smoothness term: the cost of each edge neighbour with another view,
    /// in units of the data cost (1 - quality / best quality of the face, in [0, 1]).
    double smoothness = 0.35;
    int sweeps = 6;  ///< ICM sweeps (0 = the best view per face)

    /// Throws InputError for values out of range.
    void check() const;
};

/// Quality of every (view, face) pair: 0 where the view does not see the face.
struct FaceQuality {
    int views = 0;
    int faces = 0;
    std::vector<float> quality;  ///< views x faces, row per view

    float at(int view, int face) const {
        return quality[static_cast<std::size_t>(view) * faces + face];
    }
};

/// Computes the quality of each face in each view (rendering the scene into every view; views
/// in parallel). Throws InputError when a view's image is empty or not of its intrinsics' size
/// or its intrinsics have distortion.
FaceQuality face_quality(const render::RenderScene& scene, const std::vector<TextureView>& views,
                         const SelectionOptions& options, const Progress& progress = {});

/// The edge neighbours of each triangle (-1 where the edge is a border or non-manifold).
std::vector<std::array<int, 3>> face_adjacency(const std::vector<std::array<int, 3>>& triangles);

/// The labelling.
struct Selection {
    std::vector<int> label;      ///< per face, the view index, -1 = no view sees the face
    std::size_t unseen = 0;      ///< faces with label -1
    std::size_t relabelled = 0;  ///< faces whose view the smoothness term changed
    int sweeps_run = 0;
};

/// Selects a view per face (ICM on data + Potts smoothness, see the file comment).
/// Deterministic (faces visited in index order).
Selection select_views(const FaceQuality& quality, const std::vector<std::array<int, 3>>& adjacency,
                       const SelectionOptions& options);

}  // namespace rgbd::texture
