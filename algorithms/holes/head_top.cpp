// §13 head top: see large_holes.hpp.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "algorithms/holes/inpaint_common.hpp"
#include "algorithms/holes/large_holes.hpp"
#include "toolkit/error.hpp"

namespace rgbd::holes {

using namespace detail;

namespace {

/// Steps 1-2: the top region in (u, v, h) (u, v along the horizontal frame e1, e2, h along the
/// axis, from its origin) and its top-down height map.
struct TopMap {
    std::vector<Eigen::Vector3d> top;  ///< (u, v, h) of every top point
    std::vector<Rgb> color;
    std::vector<std::uint8_t> faces_up;  ///< per top point: normal . up >= top_min_up
    double px = 0, ou = 0, ov = 0;       ///< pixel size, origin of column 0 / row 0 (m)
    int rows = 0, cols = 0;
    cv::Mat height;  ///< CV_32F, highest h per column (-inf where none; read where known)
    cv::Mat rgb;     ///< CV_8UC3, colour of that point
    cv::Mat known;   ///< CV_8U, 255 where the column's top was seen

    int col(const Eigen::Vector3d& t) const { return static_cast<int>((t.x() - ou) / px); }
    int row(const Eigen::Vector3d& t) const { return static_cast<int>((t.y() - ov) / px); }
};

/// Step 1: the points of the top region. Returns false when there are fewer than 10.
bool collect_top(const SurfacePoints& points, const std::vector<Eigen::Vector3d>& normals,
                 const BodyAxis& axis, const Eigen::Vector3d& e1, const Eigen::Vector3d& e2,
                 const InpaintOptions& options, TopMap& m, Report& info) {
    const double start = head_top_start(points, axis, options);
    for (std::size_t i = 0; i < points.size(); ++i) {
        const Eigen::Vector3d d = points.position[i] - axis.origin;
        const double h = d.dot(axis.up);
        if (h < start) continue;
        m.top.emplace_back(d.dot(e1), d.dot(e2), h);
        m.color.push_back(points.color.empty() ? Rgb{128, 128, 128} : points.color[i]);
        m.faces_up.push_back(normals[i].dot(axis.up) >= options.top_min_up);
    }
    const auto facing_up = std::count(m.faces_up.begin(), m.faces_up.end(), std::uint8_t{1});
    info["top_points"] = m.top.size();
    info["top_points_facing_down"] = m.top.size() - static_cast<std::size_t>(facing_up);
    return m.top.size() >= 10;
}

/// Step 2: the height map over every top point. A column is known when its highest point faces
/// up (options.top_min_up): a highest point facing down (a chin seen from below) has the body
/// above it, so the column's top was not seen.
void build_height_map(TopMap& m, double spacing_m, const InpaintOptions& options, Report& info) {
    m.px = options.pixel * spacing_m;
    double u0 = std::numeric_limits<double>::infinity(), v0 = u0, u1 = -u0, v1 = -u0;
    for (const auto& t : m.top) {
        u0 = std::min(u0, t.x()), u1 = std::max(u1, t.x());
        v0 = std::min(v0, t.y()), v1 = std::max(v1, t.y());
    }
    const int margin = 2;
    m.cols = static_cast<int>(std::ceil((u1 - u0) / m.px)) + 1 + 2 * margin;
    m.rows = static_cast<int>(std::ceil((v1 - v0) / m.px)) + 1 + 2 * margin;
    RGBD_CHECK_AS(AlgorithmError, double(m.cols) * m.rows < 64e6,
                  "head top: the height map would have " + std::to_string(m.cols) + " x " +
                      std::to_string(m.rows) + " pixels (spacing too small for the object?)");
    info["image"] = {m.cols, m.rows};
    m.ou = u0 - margin * m.px, m.ov = v0 - margin * m.px;
    m.height = cv::Mat(m.rows, m.cols, CV_32F, cv::Scalar(-std::numeric_limits<float>::infinity()));
    m.rgb = cv::Mat(m.rows, m.cols, CV_8UC3, cv::Scalar(0, 0, 0));
    m.known = cv::Mat(m.rows, m.cols, CV_8U, cv::Scalar(0));
    for (std::size_t i = 0; i < m.top.size(); ++i) {
        const int c = m.col(m.top[i]), r = m.row(m.top[i]);
        if (m.top[i].z() > m.height.at<float>(r, c)) {
            m.height.at<float>(r, c) = static_cast<float>(m.top[i].z());
            m.rgb.at<cv::Vec3b>(r, c) = {m.color[i].r, m.color[i].g, m.color[i].b};
            m.known.at<std::uint8_t>(r, c) = m.faces_up[i] ? 255 : 0;
        }
    }
    int unseen_tops = 0;
    for (int r = 0; r < m.rows; ++r)
        for (int c = 0; c < m.cols; ++c)
            unseen_tops +=
                !m.known.at<std::uint8_t>(r, c) && std::isfinite(m.height.at<float>(r, c));
    info["columns_topped_facing_down"] = unseen_tops;
}

/// Step 3: the hole, unknown pixels inside the convex hull of the known ones (the hull's
/// outline excluded), without components smaller than min_component or than top_component x
/// the largest one (sampling gaps on steep or rough tops, left to §11). `labels` receives the
/// components. Empty when fewer than 3 columns are known.
cv::Mat crown_hole(const TopMap& m, const InpaintOptions& options, cv::Mat& labels, Report& info) {
    std::vector<cv::Point> known_px, hull;
    cv::findNonZero(m.known, known_px);
    if (known_px.size() < 3) return cv::Mat(m.rows, m.cols, CV_8U, cv::Scalar(0));
    cv::convexHull(known_px, hull);
    cv::Mat inside(m.rows, m.cols, CV_8U, cv::Scalar(0));
    cv::fillConvexPoly(inside, hull, cv::Scalar(255));
    cv::Mat hole;
    cv::bitwise_and(inside, 255 - m.known, hole);
    // The hull's own outline pixels can be empty between two rim samples: only interior.
    cv::Mat eroded;
    cv::erode(inside, eroded, cv::Mat::ones(3, 3, CV_8U));
    cv::bitwise_and(hole, eroded, hole);
    cv::Mat stats, centroids;
    const int n = cv::connectedComponentsWithStats(hole, labels, stats, centroids, 8, CV_32S);
    int largest = 0;
    for (int l = 1; l < n; ++l) largest = std::max(largest, stats.at<int>(l, cv::CC_STAT_AREA));
    const double keep = std::max<double>(options.min_component, options.top_component * largest);
    int dropped = 0;
    for (int r = 0; r < m.rows; ++r)
        for (int c = 0; c < m.cols; ++c) {
            const int l = labels.at<int>(r, c);
            if (l > 0 && stats.at<int>(l, cv::CC_STAT_AREA) < keep) {
                hole.at<std::uint8_t>(r, c) = 0;
                ++dropped;
            }
        }
    info["components"] = n - 1;
    info["skipped_small_pixels"] = dropped;
    return hole;
}

/// An axis-aligned ellipsoid A u^2 + B v^2 + C h^2 + D u + E v + F h = 1 in coordinates
/// centred on `mean` and divided by `scale` (for conditioning).
struct Ellipsoid {
    Eigen::Matrix<double, 6, 1> k;
    Eigen::Vector3d mean;
    double scale = 1;

    /// Height of the upper sheet over (u, v) in metres; NaN where the sheet does not reach.
    double height_at(double u_m, double v_m) const {
        const double u = (u_m - mean.x()) / scale, v = (v_m - mean.y()) / scale;
        // C h^2 + F h + (A u^2 + B v^2 + D u + E v - 1) = 0, upper root.
        const double cc = k[0] * u * u + k[1] * v * v + k[3] * u + k[4] * v - 1;
        const double disc = k[5] * k[5] - 4 * k[2] * cc;
        if (disc < 0) return std::numeric_limits<double>::quiet_NaN();
        return (-k[5] + std::sqrt(disc)) / (2 * k[2]) * scale + mean.z();
    }
};

/// Step 4a: the least-squares ellipsoid through `fit` and its RMS residual in spacings
/// (geometric to first order, |f| / |grad f|). Returns false when it is no ellipsoid.
bool fit_ellipsoid(const std::vector<Eigen::Vector3d>& fit, double spacing_m, Ellipsoid& e,
                   double& rms_spacings) {
    e.mean = Eigen::Vector3d::Zero();
    for (const auto& t : fit) e.mean += t;
    e.mean /= double(fit.size());
    e.scale = 0;
    for (const auto& t : fit) e.scale = std::max(e.scale, (t - e.mean).cwiseAbs().maxCoeff());
    Eigen::Matrix<double, 6, 6> ata = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> atb = Eigen::Matrix<double, 6, 1>::Zero();
    for (const auto& t : fit) {
        const Eigen::Vector3d q = (t - e.mean) / e.scale;
        Eigen::Matrix<double, 6, 1> row;
        row << q.x() * q.x(), q.y() * q.y(), q.z() * q.z(), q.x(), q.y(), q.z();
        ata += row * row.transpose();
        atb += row;
    }
    const auto& k = e.k = ata.ldlt().solve(atb);
    double sq = 0;
    for (const auto& t : fit) {
        const Eigen::Vector3d q = (t - e.mean) / e.scale;
        const double f = k[0] * q.x() * q.x() + k[1] * q.y() * q.y() + k[2] * q.z() * q.z() +
                         k[3] * q.x() + k[4] * q.y() + k[5] * q.z() - 1;
        const Eigen::Vector3d g(2 * k[0] * q.x() + k[3], 2 * k[1] * q.y() + k[4],
                                2 * k[2] * q.z() + k[5]);
        const double d = e.scale * std::abs(f) / std::max(g.norm(), 1e-12);
        sq += d * d;
    }
    rms_spacings = std::sqrt(sq / double(fit.size())) / spacing_m;
    return k.allFinite() && k[0] > 0 && k[1] > 0 && k[2] > 0;
}

/// Step 4b [M]: the rim's residual to the ellipsoid per known pixel, the mean over its outer
/// samples (within two spacings of the highest) of the sample's height minus the ellipsoid's
/// at the sample's own place (at the pixel's centre instead, a steep rim's slope times the
/// sample's offset in the pixel would pass for a residual), then a masked 5 x 5 median (the
/// sensors' noise at grazing angles). `no_residual` is 255 where there is none.
cv::Mat rim_residual(const TopMap& m, const Ellipsoid& e, double spacing_m, cv::Mat& no_residual) {
    cv::Mat sum(m.rows, m.cols, CV_64F, cv::Scalar(0.0)),
        count(m.rows, m.cols, CV_32S, cv::Scalar(0));
    for (const auto& t : m.top) {
        const int c = m.col(t), r = m.row(t);
        if (!m.known.at<std::uint8_t>(r, c) || t.z() < m.height.at<float>(r, c) - 2 * spacing_m)
            continue;
        const double h = e.height_at(t.x(), t.y());
        if (!std::isfinite(h)) continue;
        sum.at<double>(r, c) += t.z() - h;
        ++count.at<int>(r, c);
    }
    cv::Mat raw(m.rows, m.cols, CV_32F, cv::Scalar(0.0f));
    no_residual = cv::Mat(m.rows, m.cols, CV_8U, cv::Scalar(255));
    for (int r = 0; r < m.rows; ++r)
        for (int c = 0; c < m.cols; ++c) {
            const double h = e.height_at(m.ou + (c + 0.5) * m.px, m.ov + (r + 0.5) * m.px);
            if (!m.known.at<std::uint8_t>(r, c) || !std::isfinite(h) || count.at<int>(r, c) == 0)
                continue;
            raw.at<float>(r, c) = static_cast<float>(sum.at<double>(r, c) / count.at<int>(r, c));
            no_residual.at<std::uint8_t>(r, c) = 0;
        }
    cv::Mat residual = raw.clone();
    std::vector<float> window;
    for (int r = 0; r < m.rows; ++r)
        for (int c = 0; c < m.cols; ++c) {
            if (no_residual.at<std::uint8_t>(r, c)) continue;
            window.clear();
            for (int dr = -2; dr <= 2; ++dr)
                for (int dc = -2; dc <= 2; ++dc) {
                    const int r2 = r + dr, c2 = c + dc;
                    if (r2 < 0 || c2 < 0 || r2 >= m.rows || c2 >= m.cols ||
                        no_residual.at<std::uint8_t>(r2, c2))
                        continue;
                    window.push_back(raw.at<float>(r2, c2));
                }
            std::nth_element(window.begin(), window.begin() + window.size() / 2, window.end());
            residual.at<float>(r, c) = window[window.size() / 2];
        }
    return residual;
}

/// Step 4: the crown's heights from the ellipsoid fitted to the top points at most
/// top_fit_radii hole radii below the highest (the crown's neighbourhood), moved onto the rim
/// by the residual (step 4b) carried into the hole by a harmonic solve. [M] The ellipsoid gives
/// the crown's shape, the measured rim its place: the surface meets the rim without a step and
/// the ellipsoid's misfit at the rim (a head is no ellipsoid) corrects its interior too. Returns
/// false when the crown stays open (no ellipsoid fits and not top_without_ellipsoid).
bool ellipsoid_crown(TopMap& m, const cv::Mat& hole, int hole_pixels, double spacing_m,
                     const InpaintOptions& options, Report& info) {
    double h_top = -std::numeric_limits<double>::infinity();
    for (const auto& t : m.top) h_top = std::max(h_top, t.z());
    const double hole_radius = std::sqrt(hole_pixels / std::numbers::pi) * m.px;
    const double fit_floor = options.top_fit_radii > 0 ? h_top - options.top_fit_radii * hole_radius
                                                       : -std::numeric_limits<double>::infinity();
    std::vector<Eigen::Vector3d> fit;
    for (const auto& t : m.top)
        if (t.z() >= fit_floor) fit.push_back(t);
    info["ellipsoid_fit_points"] = fit.size();
    if (fit.size() < 10) return false;
    Ellipsoid e;
    double rms = 0;
    // A top that is not an ellipsoid (a wreath, a hat) is left open (or keeps the inpainted
    // heights with top_without_ellipsoid).
    const bool valid = fit_ellipsoid(fit, spacing_m, e, rms) && rms <= options.max_ellipsoid_rms;
    info["ellipsoid_rms_spacings"] = rms;
    info["ellipsoid"] = valid;
    if (!valid) return options.top_without_ellipsoid;
    const auto& k = e.k;
    const Eigen::Vector3d c(-k[3] / (2 * k[0]), -k[4] / (2 * k[1]), -k[5] / (2 * k[2]));
    const double g = 1 + k[0] * c.x() * c.x() + k[1] * c.y() * c.y() + k[2] * c.z() * c.z();
    if (g > 0)
        info["ellipsoid_semi_axes_m"] = {e.scale * std::sqrt(g / k[0]),
                                         e.scale * std::sqrt(g / k[1]),
                                         e.scale * std::sqrt(g / k[2])};
    cv::Mat no_residual;
    cv::Mat residual = rim_residual(m, e, spacing_m, no_residual);
    telea(residual, no_residual, options.telea_radius);
    info["residual_harmonic"] = biharmonic(residual, hole, /*harmonic=*/true);
    // Every pixel the ellipsoid reaches takes ellipsoid + residual, the known ones too: only
    // hole pixels become points, but their positions and normals interpolate their neighbours,
    // which are then the smoothed rim, not its noisiest samples.
    int used = 0;
    for (int r = 0; r < m.rows; ++r)
        for (int c2 = 0; c2 < m.cols; ++c2) {
            const double h = e.height_at(m.ou + (c2 + 0.5) * m.px, m.ov + (r + 0.5) * m.px);
            if (!std::isfinite(h)) continue;  // keeps the inpainted height
            m.height.at<float>(r, c2) = static_cast<float>(h) + residual.at<float>(r, c2);
            used += hole.at<std::uint8_t>(r, c2) ? 1 : 0;
        }
    info["ellipsoid_pixels"] = used;
    return true;
}

/// Step 5: back-projection of the hole pixels at the step, normals from the height gradient.
Candidates back_project(const TopMap& m, const cv::Mat& hole, const cv::Mat& labels,
                        const BodyAxis& axis, const Eigen::Vector3d& e1, const Eigen::Vector3d& e2,
                        const InpaintOptions& options) {
    const Eigen::Vector3d& up = axis.up;
    const int n_sub = std::max(1, static_cast<int>(std::lround(options.pixel / options.step)));
    Candidates cand;
    for (int r = 0; r < m.rows; ++r)
        for (int c = 0; c < m.cols; ++c) {
            if (!hole.at<std::uint8_t>(r, c)) continue;
            const int cl = std::max(c - 1, 0), cr = std::min(c + 1, m.cols - 1);
            const int rl = std::max(r - 1, 0), rr = std::min(r + 1, m.rows - 1);
            const double hu = (m.height.at<float>(r, cr) - m.height.at<float>(r, cl)) /
                              (std::max(cr - cl, 1) * m.px);
            const double hv = (m.height.at<float>(rr, c) - m.height.at<float>(rl, c)) /
                              (std::max(rr - rl, 1) * m.px);
            const Eigen::Vector3d n = (up - hu * e1 - hv * e2).normalized();
            for (int a = 0; a < n_sub; ++a)
                for (int b = 0; b < n_sub; ++b) {
                    const double fc = c + (a + 0.5) / n_sub - 0.5;  // pixel-centre coordinates
                    const double fr = r + (b + 0.5) / n_sub - 0.5;
                    const double h = bilinear(m.height, fr, fc, false);
                    const double u = m.ou + (fc + 0.5) * m.px, v = m.ov + (fr + 0.5) * m.px;
                    cand.push(axis.origin + u * e1 + v * e2 + h * up, n, pixel_rgb(m.rgb, r, c),
                              static_cast<std::uint32_t>(labels.at<int>(r, c)));
                }
        }
    return cand;
}

}  // namespace

double head_top_start(const SurfacePoints& points, const BodyAxis& axis,
                      const InpaintOptions& options) {
    double h_min = std::numeric_limits<double>::infinity(), h_max = -h_min;
    for (const auto& p : points.position) {
        const double h = (p - axis.origin).dot(axis.up);
        h_min = std::min(h_min, h);
        h_max = std::max(h_max, h);
    }
    return h_max - options.top_fraction * (h_max - h_min);
}

FillResult fill_head_top(const SurfacePoints& points, const std::vector<Eigen::Vector3d>& normals,
                         const BodyAxis& axis, double spacing_m,
                         const std::vector<SensorView>& sensors, const InpaintOptions& options,
                         Report* report, const Progress& progress) {
    options.check();
    check_input(points, normals, spacing_m);
    Stopwatch watch;
    FillResult result;
    Report info;
    auto finish = [&]() {
        info["points_added"] = result.position.size();
        info["time_s"] = watch.seconds();
        if (report) (*report)["head_top"] = info;
        return result;
    };
    Eigen::Vector3d e1, e2;
    horizontal_frame(axis.up, e1, e2);
    TopMap m;
    if (!collect_top(points, normals, axis, e1, e2, options, m, info)) return finish();
    build_height_map(m, spacing_m, options, info);
    cv::Mat labels;
    const cv::Mat hole = crown_hole(m, options, labels, info);
    const int hole_pixels = cv::countNonZero(hole);
    info["hole_pixels"] = hole_pixels;
    if (hole_pixels == 0) return finish();
    // Step 4: Telea on height and colour (every unknown pixel, so none is a known zero). The
    // height and the colour are independent chains (OpenCV's Telea is sequential): side by side.
    const cv::Mat unknown = 255 - m.known;
    m.height.setTo(0.0f, unknown);
    nlohmann::json colour_info;
    std::optional<bool> biharmonic_done;
    tbb::parallel_invoke(
        [&] {
            telea(m.height, unknown, options.telea_radius);
            if (options.biharmonic) biharmonic_done = biharmonic(m.height, hole);
        },
        [&] {
            telea(m.rgb, unknown, options.telea_radius);
            colour_info = inpaint_colour(m.rgb, hole, m.known, options);
        });
    info["colour"] = std::move(colour_info);
    if (biharmonic_done) info["biharmonic"] = *biharmonic_done;
    if (!report_progress(progress, 0.4)) throw AlgorithmError("cancelled");
    if (options.ellipsoid && !ellipsoid_crown(m, hole, hole_pixels, spacing_m, options, info)) {
        // Not an ellipsoid (a wreath, a hat): nothing trustworthy to continue; the crown stays
        // open rather than invented.
        info["hole_pixels_left_open"] = hole_pixels;
        return finish();
    }
    if (!report_progress(progress, 0.7)) throw AlgorithmError("cancelled");
    Candidates cand = back_project(m, hole, labels, axis, e1, e2, options);
    keep_candidates(cand, points, sensors, spacing_m, options, FillMechanism::kHeadTop, result,
                    info);
    if (!report_progress(progress, 1.0)) throw AlgorithmError("cancelled");
    return finish();
}

}  // namespace rgbd::holes
