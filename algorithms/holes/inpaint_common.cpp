#include "algorithms/holes/inpaint_common.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <Eigen/Sparse>
#include <Eigen/SparseLU>
#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <opencv2/photo.hpp>
#include <optional>

#include "algorithms/holes/exemplar_inpaint.hpp"
#include "algorithms/holes/free_space.hpp"
#include "algorithms/internal/kd_tree.hpp"
#include "toolkit/error.hpp"

namespace rgbd::holes {

void InpaintOptions::check() const {
    check_range("inpaint: pixel size", pixel, Range::closed(0.5, 10), "spacings");
    check_range("inpaint: Telea radius", telea_radius, Range::closed(1, 50), "pixels");
    RGBD_CHECK(patch >= 3 && patch <= 51 && patch % 2 == 1,
               "inpaint: the exemplar patch side must be odd, in [3, 51] pixels");
    check_range("inpaint: the exemplar search window", search_window, Range::closed(1, 100),
                "hole boxes");
    check_range("inpaint: wrap padding", wrap, Range::closed(0, 0.5), "of the width");
    check_range("inpaint: minimum component", min_component, Range::closed(1, 1000000), "pixels");
    check_range("inpaint: step", step, Range::closed(0.25, 10), "spacings");
    check_range("inpaint: clearance", clearance, Range::closed(0, 5), "spacings");
    check_range("inpaint: minimum rim n.radial", min_rim_radial, Range::closed(-1, 1));
    check_range("inpaint: top fraction", top_fraction, Range::open_closed(0, 0.5));
    check_range("inpaint: top minimum up component", top_min_up, Range::closed(-1, 1));
    check_range("inpaint: ellipsoid fit depth", top_fit_radii, Range::closed(0, 100), "hole radii");
    check_range("inpaint: top component share", top_component, Range::closed(0, 1));
    check_visibility("inpaint", visible_max_angle_deg, ray_clearance);
    RGBD_CHECK(std::isfinite(max_ellipsoid_rms) && max_ellipsoid_rms > 0,
               "inpaint: the ellipsoid's residual limit must be positive, got " +
                   format_number(max_ellipsoid_rms));
    RGBD_CHECK(std::isfinite(max_biharmonic_slope) && max_biharmonic_slope >= 0,
               "inpaint: the biharmonic slope limit must not be negative, got " +
                   format_number(max_biharmonic_slope));
    check_range("inpaint: the open rim share", max_open_rim, Range::closed(0, 1));
    RGBD_CHECK(max_step_rms > 0, "inpaint: the step test's RMS limit must be positive");
    check_range("inpaint: the contradicted share", max_contradicted, Range::closed(0, 1));
    free_space.check();
}

namespace detail {

namespace {

/// Drops the candidates of hole components that a sensor saw through (§10's visibility test on
/// the component's centre, mean normal and radius). Returns the number of components dropped.
int drop_openings(Candidates& candidates, const std::vector<SensorView>& sensors,
                  const internal::KdTree& tree, double spacing_m, const InpaintOptions& options) {
    auto& position = candidates.position;
    auto& normal = candidates.normal;
    auto& color = candidates.color;
    auto& loop = candidates.loop;
    if (sensors.empty() || options.fill_openings || position.empty()) return 0;
    const std::uint32_t n = *std::max_element(loop.begin(), loop.end()) + 1;
    std::vector<Eigen::Vector3d> centre(n, Eigen::Vector3d::Zero()),
        mean_n(n, Eigen::Vector3d::Zero());
    std::vector<std::size_t> count(n, 0);
    for (std::size_t i = 0; i < position.size(); ++i) {
        centre[loop[i]] += position[i];
        mean_n[loop[i]] += normal[i];
        ++count[loop[i]];
    }
    std::vector<double> radius(n, 0.0);
    for (std::uint32_t l = 0; l < n; ++l)
        if (count[l]) centre[l] /= double(count[l]);
    for (std::size_t i = 0; i < position.size(); ++i)
        radius[loop[i]] = std::max(radius[loop[i]], (position[i] - centre[loop[i]]).norm());
    std::vector<std::uint8_t> open(n, 0);
    int dropped = 0;
    tbb::parallel_for(std::uint32_t(0), n, [&](std::uint32_t l) {
        if (!count[l] || mean_n[l].norm() == 0) return;
        for (const auto& s : sensors)
            if (sensor_sees_region(s, centre[l], mean_n[l].normalized(), radius[l], spacing_m, tree,
                                   options.visible_max_angle_deg, options.ray_clearance)) {
                open[l] = 1;
                return;
            }
    });
    for (auto o : open) dropped += o;
    std::size_t k = 0;
    for (std::size_t i = 0; i < position.size(); ++i) {
        if (open[loop[i]]) continue;
        position[k] = position[i];
        normal[k] = normal[i];
        color[k] = color[i];
        loop[k++] = loop[i];
    }
    position.resize(k);
    normal.resize(k);
    color.resize(k);
    loop.resize(k);
    return dropped;
}

}  // namespace

void check_input(const SurfacePoints& points, const std::vector<Eigen::Vector3d>& normals,
                 double spacing_m) {
    RGBD_CHECK(!points.position.empty(), "inpaint: no points");
    RGBD_CHECK(normals.size() == points.size(), "inpaint: one normal per point is needed");
    RGBD_CHECK(points.color.empty() || points.color.size() == points.size(),
               "inpaint: one colour per point is needed");
    RGBD_CHECK(std::isfinite(spacing_m) && spacing_m > 0, "inpaint: the spacing must be positive");
    for (const auto& p : points.position)
        RGBD_CHECK(p.allFinite(), "inpaint: non-finite point coordinates");
}

/// Right-handed frame (e1, e2, up).
void horizontal_frame(const Eigen::Vector3d& up, Eigen::Vector3d& e1, Eigen::Vector3d& e2) {
    const Eigen::Vector3d seed =
        std::abs(up.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
    e1 = (seed - seed.dot(up) * up).normalized();
    e2 = up.cross(e1);
}

/// Telea on every pixel of `unknown` (8-bit mask, non-zero = unknown), in place. Pixels outside
/// the object are unknown too, so that they never act as known zeros.
/// OpenCV's Telea adds a normalised gradient term and a rounding offset of 0.5 (meant for 8-bit
/// levels) to every pixel it fills, whatever the type: on a float image in metres that is an
/// error of metres. Float images (metres) are therefore inpainted in micrometres above their
/// known minimum, where the offset is a few micrometres.
void telea(cv::Mat& image, const cv::Mat& unknown, double radius) {
    if (cv::countNonZero(unknown) == 0) return;
    cv::Mat out;
    if (image.type() == CV_32F) {
        double lo = 0, hi = 0;
        cv::minMaxLoc(image, &lo, &hi, nullptr, nullptr, 255 - unknown);
        cv::Mat scaled;
        image.convertTo(scaled, CV_32F, 1e6, -lo * 1e6);
        scaled.setTo(0.0f, unknown);
        cv::inpaint(scaled, unknown, out, radius, cv::INPAINT_TELEA);
        out.convertTo(image, CV_32F, 1e-6, lo);
        return;
    }
    cv::inpaint(image, unknown, out, radius, cv::INPAINT_TELEA);
    image = out;
}

constexpr std::size_t kBiharmonicMaxPixels = 250000;

/// Biharmonic fill [M] of the float image on the non-zero pixels of `mask`: solves
/// Laplacian^2 u = 0 there (13-point stencil; the other pixels are fixed boundary values, image
/// borders clamped) with a sparse LU. Unlike OpenCV's Telea, which averages its neighbours and
/// so flattens a dome, it continues the rim's slope and curvature into the hole. Returns false
/// (image unchanged) when the solve fails or the hole has more than kBiharmonicMaxPixels.
bool biharmonic(cv::Mat& img, const cv::Mat& mask, bool harmonic) {
    std::vector<cv::Point> pixels;
    cv::findNonZero(mask, pixels);
    if (pixels.empty()) return true;
    // The sparse LU's fill-in grows fast with the unknowns: a scene with holes of this size is
    // no bust; Telea's result stays.
    if (pixels.size() > kBiharmonicMaxPixels) return false;
    const int rows = img.rows, cols = img.cols;
    cv::Mat index(rows, cols, CV_32S, cv::Scalar(-1));
    for (std::size_t i = 0; i < pixels.size(); ++i) index.at<int>(pixels[i]) = static_cast<int>(i);
    std::vector<Eigen::Triplet<double>> triplets;
    triplets.reserve(pixels.size() * 13);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(pixels.size()));
    static const int kLaplace[5][3] = {{0, 0, 4}, {-1, 0, -1}, {1, 0, -1}, {0, -1, -1}, {0, 1, -1}};
    static const int kStencil[13][3] = {
        {0, 0, 20}, {-1, 0, -8}, {1, 0, -8}, {0, -1, -8}, {0, 1, -8}, {-1, -1, 2}, {-1, 1, 2},
        {1, -1, 2}, {1, 1, 2},   {-2, 0, 1}, {2, 0, 1},   {0, -2, 1}, {0, 2, 1}};
    for (std::size_t i = 0; i < pixels.size(); ++i) {
        for (int k = 0; k < (harmonic ? 5 : 13); ++k) {
            const int* st = harmonic ? kLaplace[k] : kStencil[k];
            const int r = std::clamp(pixels[i].y + st[0], 0, rows - 1);
            const int c = std::clamp(pixels[i].x + st[1], 0, cols - 1);
            const int j = index.at<int>(r, c);
            if (j >= 0)
                triplets.emplace_back(static_cast<int>(i), j, st[2]);
            else
                rhs[static_cast<Eigen::Index>(i)] -= st[2] * double(img.at<float>(r, c));
        }
    }
    Eigen::SparseMatrix<double> a(static_cast<Eigen::Index>(pixels.size()),
                                  static_cast<Eigen::Index>(pixels.size()));
    a.setFromTriplets(triplets.begin(), triplets.end());
    Eigen::SparseLU<Eigen::SparseMatrix<double>> lu;
    lu.compute(a);
    if (lu.info() != Eigen::Success) return false;
    const Eigen::VectorXd u = lu.solve(rhs);
    if (lu.info() != Eigen::Success || !u.allFinite()) return false;
    for (std::size_t i = 0; i < pixels.size(); ++i)
        img.at<float>(pixels[i]) = static_cast<float>(u[static_cast<Eigen::Index>(i)]);
    return true;
}

/// §12.2 colour of the `target` pixels: Criminisi's exemplars from the `source` pixels over the
/// Telea result already in `color` (kept where no exemplar fits). Report: method, patches,
/// pixels filled by exemplars, pixels left to Telea, time_s.
nlohmann::json inpaint_colour(cv::Mat& color, const cv::Mat& target, const cv::Mat& source,
                              const InpaintOptions& options) {
    nlohmann::json info;
    if (options.colour == ColourInpaint::kTelea) {
        info["method"] = "telea";
        return info;
    }
    Stopwatch watch;
    ExemplarOptions eo;
    eo.patch = options.patch;
    eo.search_window = options.search_window;
    const ExemplarStats s = exemplar_inpaint(color, target, source, eo);
    info["method"] = "criminisi";
    info["patches"] = s.patches;
    info["exemplar_pixels"] = s.filled;
    info["telea_pixels"] = s.unfilled;
    info["windows_widened"] = s.window_widened;
    info["patch"] = s.patch;
    info["time_s"] = watch.seconds();
    return info;
}

Rgb pixel_rgb(const cv::Mat& color, int row, int col) {
    const cv::Vec3b c = color.at<cv::Vec3b>(row, col);
    return {c[0], c[1], c[2]};
}

/// The common end of both fills: the candidates of components a sensor saw through are
/// dropped (info["skipped_seen_through"]); of the rest, those within the clearance of `points`
/// are dropped, then those in space a sensor saw empty (free_space.hpp; a component with more than
/// max_contradicted of them goes whole: info["carved_components"], info["carved_points"]);
/// the survivors join `result` in the order given.
void keep_candidates(Candidates& cand, const SurfacePoints& points,
                     const std::vector<SensorView>& sensors, double spacing_m,
                     const InpaintOptions& options, FillMechanism mechanism, FillResult& result,
                     Report& info) {
    // The kd-tree (a sequential build) beside the free-space maps (parallel over the sensors).
    const bool carve =
        options.carve && !options.fill_openings && !sensors.empty() && !cand.position.empty();
    std::optional<internal::KdTree> kd;
    std::optional<FreeSpace> free_space;
    tbb::parallel_invoke([&] { kd.emplace(points.position); },
                         [&] {
                             free_space.emplace(
                                 carve ? points.position : std::vector<Eigen::Vector3d>{},
                                 carve ? sensors : std::vector<SensorView>{}, spacing_m,
                                 options.free_space);
                         });
    const internal::KdTree& tree = *kd;
    const FreeSpace& free = *free_space;
    info["skipped_seen_through"] = drop_openings(cand, sensors, tree, spacing_m, options);
    const std::size_t n = cand.position.size();
    // 0 = dropped, 1 = kept, 2 = in free space.
    std::vector<std::uint8_t> keep(n, 0);
    const double c2 = options.clearance * spacing_m * options.clearance * spacing_m;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 256), [&](const auto& range) {
        for (std::size_t i = range.begin(); i != range.end(); ++i) {
            if (!cand.position[i].allFinite() || !cand.normal[i].allFinite()) continue;
            std::uint32_t nearest;
            double d2;
            if (c2 > 0 && tree.nearest_within(cand.position[i], c2, nearest, d2)) continue;
            keep[i] = carve && free.seen_empty(cand.position[i], cand.normal[i]) >= 0 ? 2 : 1;
        }
    });
    const std::uint32_t n_loops = n ? *std::max_element(cand.loop.begin(), cand.loop.end()) + 1 : 0;
    std::vector<std::size_t> total(n_loops, 0), empty(n_loops, 0);
    for (std::size_t i = 0; i < n; ++i) {
        total[cand.loop[i]] += keep[i] > 0;
        empty[cand.loop[i]] += keep[i] == 2;
    }
    std::size_t carved_points = 0;
    int carved_components = 0;
    for (std::uint32_t l = 0; l < n_loops; ++l)
        if (total[l] && double(empty[l]) > options.max_contradicted * double(total[l])) {
            ++carved_components;
            carved_points += total[l];
            total[l] = 0;
        } else {
            carved_points += empty[l];
        }
    info["carved_components"] = carved_components;
    info["carved_points"] = carved_points;
    for (std::size_t i = 0; i < n; ++i) {
        if (keep[i] != 1 || total[cand.loop[i]] == 0) continue;
        result.position.push_back(cand.position[i]);
        result.normal.push_back(cand.normal[i]);
        result.color.push_back(cand.color[i]);
        result.mechanism.push_back(mechanism);
        result.loop.push_back(cand.loop[i]);
    }
}

double bilinear(const cv::Mat& img, double row, double col, bool wrap_cols) {
    const int rows = img.rows, cols = img.cols;
    row = std::clamp(row, 0.0, double(rows - 1));
    if (!wrap_cols) col = std::clamp(col, 0.0, double(cols - 1));
    const int r0 = std::min(static_cast<int>(std::floor(row)), rows - 1);
    const int r1 = std::min(r0 + 1, rows - 1);
    const int c0f = static_cast<int>(std::floor(col));
    const double fr = row - r0, fc = col - c0f;
    auto at = [&](int r, int c) {
        c = wrap_cols ? ((c % cols) + cols) % cols : std::clamp(c, 0, cols - 1);
        return double(img.at<float>(r, c));
    };
    return (1 - fr) * ((1 - fc) * at(r0, c0f) + fc * at(r0, c0f + 1)) +
           fr * ((1 - fc) * at(r1, c0f) + fc * at(r1, c0f + 1));
}
}  // namespace detail

}  // namespace rgbd::holes
