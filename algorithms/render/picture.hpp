// Pictures of meshes and point clouds for reports (rgbd-render, rgbd-eval --report): a pinhole
// camera fitted to the object from a chosen or automatic direction, triangles through the
// z-buffer rasteriser (rasterizer.hpp) with vertex colours or Lambert + ambient grey shading,
// points splatted as discs with a depth test, and a heat-map mode that colours by a per-vertex
// value (turbo colour map) with a colour bar. Software only, parallel over rows (oneTBB); the
// picture does not depend on the number of threads.
// Sources: Pineda 1988 (edge functions, see rasterizer.hpp); Zwicker et al., "Surface
// splatting", SIGGRAPH 2001 (screen-space discs, here without the EWA filter); Mikhailov,
// "Turbo, an improved rainbow colormap" (Google AI blog, 2019), via OpenCV's COLORMAP_TURBO.
// See also: Open3D `visualization.rendering.OffscreenRenderer` (needs EGL), MeshLab snapshots.
#pragma once

#include <Eigen/Core>
#include <array>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "toolkit/camera.hpp"
#include "toolkit/mesh.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/pose.hpp"
#include "toolkit/textured_mesh.hpp"

namespace rgbd::render {

/// What to draw, in the world frame.
struct Geometry {
    std::vector<Eigen::Vector3d> vertices;
    std::vector<std::array<int, 3>> triangles;  ///< empty: the vertices are drawn as points
    std::vector<Rgb> colors;                    ///< per vertex, or empty
    std::vector<Eigen::Vector3d> normals;       ///< per point (clouds), or empty
    std::vector<double> scalars;                ///< per vertex heat-map values, or empty
    std::vector<Pose> sensors;                  ///< world_from_sensor of the source views
    /// Texture (meshes, optional): atlases (CV_8UC3, BGR) and per triangle its atlas (-1: the
    /// vertex colours) and its corners' texture coordinates (glTF convention: [0, 1], origin
    /// top-left, v down).
    std::vector<cv::Mat> atlases;
    std::vector<int> triangle_atlas;
    std::vector<std::array<Eigen::Vector2f, 3>> corner_uvs;

    bool is_mesh() const { return !triangles.empty(); }
    bool is_textured() const { return !atlases.empty(); }
    /// Throws InputError naming `what` for no vertices, non-finite coordinates, triangle
    /// indices out of range or per-vertex arrays of the wrong size.
    void check(const std::string& what) const;
};

/// The triangles (polygons fanned), vertex colours when the mesh has them.
Geometry from_mesh(const Mesh& mesh);
/// The triangles, vertex colours and texture (when it has one) of a textured mesh
/// (rgbd-texture, .obj/.glb; rgbd-render, the report of rgbd-reconstruct -o model.glb).
Geometry from_textured_mesh(const TexturedMesh& mesh);
/// The points of every view in the world frame (a sensor-frame view is moved by its pose; one
/// without a pose, such as a plain point file, is taken as it is), with colours when every
/// view has them, normals when every view has them, and the views' sensor poses (a
/// sensor-frame view with intrinsics but no pose: a sensor at the origin).
Geometry from_views(const std::vector<PointCloud>& views);

/// Where the camera looks from. kAuto is a three-quarter view (35 degrees to the right of the
/// front, 20 degrees above).
enum class ViewDirection { kAuto, kFront, kBack, kLeft, kRight, kTop };
/// "auto", "front", "back", "left", "right", "top"; InputError otherwise.
ViewDirection parse_view_direction(const std::string& name);

/// Which way is up and which side is the front (unit vectors, front perpendicular to up;
/// front points from the object towards a viewer in front of it).
struct Orientation {
    Eigen::Vector3d up = Eigen::Vector3d::UnitY();
    Eigen::Vector3d front = Eigen::Vector3d::UnitZ();
};

/// Up: `up` when given, else the mean "up" of the sensors (minus their image y axes), else +y.
/// Front: towards the sensors' mean position when they stand on one side of `centre`; for a
/// ring around it, towards the first sensor; without sensors, the axis among +z, +x, -z, -x
/// least aligned with up. InputError for a zero or non-finite `up`.
Orientation guess_orientation(const std::vector<Pose>& sensors, const Eigen::Vector3d& centre,
                              const std::optional<Eigen::Vector3d>& up);

/// Options of fit_camera().
struct CameraOptions {
    int width = 960;
    int height = 720;
    ViewDirection view = ViewDirection::kAuto;
    std::optional<double> azimuth_deg;    ///< overrides the direction's azimuth (0 = front,
                                          ///< 90 = from the right)
    std::optional<double> elevation_deg;  ///< overrides its elevation (90 = from above)
    double margin = 0.05;                 ///< free fraction of the image on each side
    double distance_factor = 3.0;         ///< camera distance / object radius (perspective)

    /// InputError for sizes outside 16..16384, non-finite angles, |elevation| > 90, margin
    /// outside [0, 0.4) or distance_factor <= 1.2.
    void check() const;
};

/// A pinhole camera (no distortion) and its pose.
struct Camera {
    PinholeIntrinsics intrinsics;
    Pose world_from_camera = Pose::Identity();
};

/// Fits a camera to `points`: it looks at the centre of their robust bounding box (0.2% and
/// 99.8% quantiles per axis) from the chosen direction, at distance_factor times its
/// half-diagonal, and the focal length and principal point fit the projection of the points
/// inside that box into the image less the margin, centred. InputError for no finite point.
Camera fit_camera(const std::vector<Eigen::Vector3d>& points, const Orientation& orientation,
                  const CameraOptions& options);

/// Options of render_picture().
struct PictureOptions {
    Rgb background{255, 255, 255};
    double point_radius_px = 0.0;       ///< splat radius; 0 = from the point spacing
    std::optional<double> scalar_min;   ///< heat-map range; default 0 for non-negative
    std::optional<double> scalar_max;   ///< values (else the minimum) to the 98th percentile
    std::string scalar_label;           ///< written above the colour bar, e.g. "error (mm)"
    double scalar_display_scale = 1.0;  ///< factor for the bar's numbers (1000: m -> mm)

    /// InputError for a negative or non-finite radius, non-finite range or scale, min >= max.
    void check() const;
};

/// A rendered picture.
struct Picture {
    cv::Mat image;                      ///< CV_8UC3, BGR; the colour bar strip is on the right
    Camera camera;                      ///< the camera of the model area
    cv::Rect model_area;                ///< the camera's pixels (left part of image)
    std::optional<cv::Rect> color_bar;  ///< bar pixels (top row = scalar_max), heat maps only
    double scalar_min = 0.0, scalar_max = 0.0;
    std::size_t covered_pixels = 0;  ///< model pixels that show the object
};

/// The heat-map colour of a value t in [0, 1] (clamped): OpenCV's turbo colour map.
Rgb heat_color(double t);

/// Renders `geometry` seen by `camera`. Meshes: the texture, sampled bilinearly at the
/// perspective-correct texture coordinates, or per-pixel barycentric interpolation of vertex
/// colours (both lightly shaded, alike), of scalars (unshaded heat map) or of smooth vertex normals
/// (grey, Lambert with a light above-left of the camera, two-sided, plus ambient). Points: discs
/// with a depth test (ties to the lower index), shaded by their normals when there are any, else by
/// depth. With scalars, a colour bar strip is appended on the right.
Picture render_picture(const Geometry& geometry, const Camera& camera,
                       const PictureOptions& options = {});

}  // namespace rgbd::render
