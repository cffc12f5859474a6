// Software rasteriser with a z-buffer (synthetic RGB-D captures, rgbd-render): renders a triangle
// mesh into a pinhole camera exactly (depth = ray/triangle intersection at every pixel centre, by
// perspective-correct interpolation of 1/z), plus the surface normal and the triangle id per
// pixel, and a colour image from a shading callback. Parallel over bands of rows (oneTBB);
// the result does not depend on the number of threads (ties go to the lower triangle id).
// Source: Pineda, "A parallel algorithm for polygon rasterization", SIGGRAPH 1988 (edge
// functions); docs/algorithms.md, synthetic ground truth. See also: picture.hpp (rgbd-render),
// validation/synth/synthesize.hpp.
#pragma once

#include <Eigen/Core>
#include <array>
#include <functional>
#include <opencv2/core.hpp>
#include <vector>

#include "toolkit/camera.hpp"
#include "toolkit/mesh.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/pose.hpp"

namespace rgbd::render {

/// A triangle soup in the world frame, ready to render (built once, rendered many times).
class RenderScene {
public:
    /// Copies the triangles of `mesh_world` (faces with more than 3 vertices are fanned).
    /// Throws InputError for a mesh without faces or with non-finite coordinates.
    explicit RenderScene(const Mesh& mesh_world);
    /// A triangle soup given directly. Throws InputError for no triangles, an index out of
    /// range or non-finite coordinates.
    RenderScene(std::vector<Eigen::Vector3d> vertices, std::vector<std::array<int, 3>> triangles);

    const std::vector<Eigen::Vector3d>& vertices() const { return vertices_; }
    const std::vector<std::array<int, 3>>& triangles() const { return triangles_; }
    /// Unit normal of each triangle, world frame (zero for degenerate triangles).
    const std::vector<Eigen::Vector3d>& normals() const { return normals_; }

private:
    void compute_normals();

    std::vector<Eigen::Vector3d> vertices_;
    std::vector<std::array<int, 3>> triangles_;
    std::vector<Eigen::Vector3d> normals_;
};

/// Options of the rasteriser.
struct RasterOptions {
    double near_m = 0.05;  ///< triangles with a vertex closer than this (camera z) are skipped
    int band_rows = 16;    ///< rows per parallel work item (any value gives the same result)

    /// Throws InputError for near_m <= 0 or band_rows < 1.
    void check() const;
};

/// Result of a depth render, one entry per pixel.
struct DepthRender {
    cv::Mat depth;     ///< CV_64FC1, camera z in metres; NaN where no triangle is hit
    cv::Mat normal;    ///< CV_32FC3, unit surface normal in the camera frame, facing the camera
    cv::Mat triangle;  ///< CV_32SC1, index into RenderScene::triangles(), -1 = none

    /// Depth as CV_32FC1 (NaN = none), the format of RgbdFrame::depth.
    cv::Mat depth_float() const;
};

/// Renders depth, normals and triangle ids seen by a camera at `world_from_camera`.
/// `intrinsics` must have no distortion (the rasteriser is exact for pinhole cameras only);
/// throws InputError otherwise.
DepthRender render_depth(const RenderScene& scene, const PinholeIntrinsics& intrinsics,
                         const Pose& world_from_camera, const RasterOptions& options = {});

/// Colour of a visible surface point given in the world frame. Must be thread-safe.
using Shader = std::function<Rgb(const Eigen::Vector3d& p_world, int triangle)>;

/// Renders a colour image (CV_8UC3, BGR) seen by a camera at `world_from_camera`: every pixel
/// covered by the mesh gets shader(point on the nearest triangle along the pixel's ray),
/// the others `background`. Visibility is resolved in this camera, so occlusions are its own.
cv::Mat render_color(const RenderScene& scene, const PinholeIntrinsics& intrinsics,
                     const Pose& world_from_camera, const Shader& shader, Rgb background,
                     const RasterOptions& options = {});

}  // namespace rgbd::render
