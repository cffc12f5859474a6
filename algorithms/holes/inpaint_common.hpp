// Shared steps of the large-hole (§12) and head-top (§13) fills: input checks, the horizontal
// frame of the body axis, Telea and biharmonic inpainting of images, the colour inpainting, and
// the common end of both fills (seen-through holes, clearance, free space). Internal to
// algorithms/holes.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <vector>

#include "algorithms/holes/large_holes.hpp"

namespace rgbd::holes::detail {

/// InputError unless there are points, one normal per point, one colour per point (or none),
/// finite coordinates and a positive spacing.
void check_input(const SurfacePoints& points, const std::vector<Eigen::Vector3d>& normals,
                 double spacing_m);

/// Right-handed frame (e1, e2, up).
void horizontal_frame(const Eigen::Vector3d& up, Eigen::Vector3d& e1, Eigen::Vector3d& e2);

/// §12.2 Telea on every pixel of `unknown` (8-bit mask, non-zero = unknown), in place; float
/// images (metres) are inpainted in micrometres above their known minimum (OpenCV's rounding
/// offset of 0.5 is meant for 8-bit levels).
void telea(cv::Mat& image, const cv::Mat& unknown, double radius);

/// §12.2 [M] biharmonic fill of the float image on the non-zero pixels of `mask` (continues
/// the rim's slope and curvature), or with `harmonic` the harmonic one (Laplace: continues
/// the rim's values only, stays within their range). False (image unchanged) when the solve
/// fails or is too big.
bool biharmonic(cv::Mat& img, const cv::Mat& mask, bool harmonic = false);

/// §12.2 colour of the `target` pixels: Criminisi's exemplars from the `source` pixels over the
/// Telea result already in `color`. Report: method, patches, pixels, time_s.
nlohmann::json inpaint_colour(cv::Mat& color, const cv::Mat& target, const cv::Mat& source,
                              const InpaintOptions& options);

/// Colour of a pixel of an 8-bit, 3-channel image.
Rgb pixel_rgb(const cv::Mat& color, int row, int col);

/// New points proposed by a fill, in parallel arrays: position, normal, colour and the hole
/// component (`loop`) of each.
struct Candidates {
    std::vector<Eigen::Vector3d> position, normal;
    std::vector<Rgb> color;
    std::vector<std::uint32_t> loop;

    void push(const Eigen::Vector3d& p, const Eigen::Vector3d& n, Rgb c, std::uint32_t l) {
        position.push_back(p);
        normal.push_back(n);
        color.push_back(c);
        loop.push_back(l);
    }
};

/// The common end of both fills: the candidates of components a sensor saw through are
/// dropped (info["skipped_seen_through"]); of the rest, those within the clearance of `points`
/// are dropped, then those in space a sensor saw empty (free_space.hpp, when options.carve; a
/// component with more than max_contradicted of them goes whole: info["carved_components"],
/// info["carved_points"]); the survivors join `result` in the order given.
void keep_candidates(Candidates& cand, const SurfacePoints& points,
                     const std::vector<SensorView>& sensors, double spacing_m,
                     const InpaintOptions& options, FillMechanism mechanism, FillResult& result,
                     Report& info);

/// Bilinear sample of a float image at (row, col) in pixel-centre coordinates, rows clamped,
/// columns wrapped (the cylinder) or clamped.
double bilinear(const cv::Mat& img, double row, double col, bool wrap_cols);

}  // namespace rgbd::holes::detail
