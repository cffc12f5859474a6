// §13 head top: see large_holes.hpp.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "algorithms/holes/inpaint_common.hpp"
#include "algorithms/holes/large_holes.hpp"
#include "toolkit/error.hpp"

namespace rgbd::holes {

using namespace detail;

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
    Eigen::Vector3d e1, e2;
    horizontal_frame(axis.up, e1, e2);
    const Eigen::Vector3d& up = axis.up;
    const double start = head_top_start(points, axis, options);
    // Step 1-2: the top region in (u, v, h) and its top-down height map.
    std::vector<Eigen::Vector3d> top;  // (u, v, h)
    std::vector<Rgb> top_color;
    for (std::size_t i = 0; i < points.size(); ++i) {
        const Eigen::Vector3d d = points.position[i] - axis.origin;
        const double h = d.dot(up);
        if (h < start) continue;
        top.emplace_back(d.dot(e1), d.dot(e2), h);
        top_color.push_back(points.color.empty() ? Rgb{128, 128, 128} : points.color[i]);
    }
    Report info;
    info["top_points"] = top.size();
    auto finish = [&]() {
        info["points_added"] = result.position.size();
        info["time_s"] = watch.seconds();
        if (report) (*report)["head_top"] = info;
        return result;
    };
    if (top.size() < 10) return finish();
    const double px = options.pixel * spacing_m;
    double u0 = std::numeric_limits<double>::infinity(), v0 = u0, u1 = -u0, v1 = -u0;
    for (const auto& t : top) {
        u0 = std::min(u0, t.x()), u1 = std::max(u1, t.x());
        v0 = std::min(v0, t.y()), v1 = std::max(v1, t.y());
    }
    const int margin = 2;
    const int cols = static_cast<int>(std::ceil((u1 - u0) / px)) + 1 + 2 * margin;
    const int rows = static_cast<int>(std::ceil((v1 - v0) / px)) + 1 + 2 * margin;
    RGBD_CHECK_AS(AlgorithmError, double(cols) * rows < 64e6,
                  "head top: the height map would have " + std::to_string(cols) + " x " +
                      std::to_string(rows) + " pixels (spacing too small for the object?)");
    info["image"] = {cols, rows};
    const double ou = u0 - margin * px, ov = v0 - margin * px;
    cv::Mat height(rows, cols, CV_32F, cv::Scalar(-std::numeric_limits<float>::infinity()));
    cv::Mat color(rows, cols, CV_8UC3, cv::Scalar(0, 0, 0));
    cv::Mat known(rows, cols, CV_8U, cv::Scalar(0));
    for (std::size_t i = 0; i < top.size(); ++i) {
        const int c = static_cast<int>((top[i].x() - ou) / px);
        const int r = static_cast<int>((top[i].y() - ov) / px);
        if (top[i].z() > height.at<float>(r, c)) {
            height.at<float>(r, c) = static_cast<float>(top[i].z());
            color.at<cv::Vec3b>(r, c) = {top_color[i].r, top_color[i].g, top_color[i].b};
            known.at<std::uint8_t>(r, c) = 255;
        }
    }
    // The outer surface's height per pixel without the bias of the largest of several noisy
    // samples: the mean of the samples within two spacings below the largest (the ellipsoid's
    // residual at the rim, step 4).
    cv::Mat outer_sum(rows, cols, CV_64F, cv::Scalar(0.0)),
        outer_count(rows, cols, CV_32S, cv::Scalar(0));
    for (std::size_t i = 0; i < top.size(); ++i) {
        const int c = static_cast<int>((top[i].x() - ou) / px);
        const int r = static_cast<int>((top[i].y() - ov) / px);
        if (top[i].z() < height.at<float>(r, c) - 2 * spacing_m) continue;
        outer_sum.at<double>(r, c) += top[i].z();
        ++outer_count.at<int>(r, c);
    }
    // Step 3: hole = unknown pixels inside the convex hull of the known ones.
    std::vector<cv::Point> known_px, hull;
    cv::findNonZero(known, known_px);
    cv::convexHull(known_px, hull);
    cv::Mat inside(rows, cols, CV_8U, cv::Scalar(0));
    cv::fillConvexPoly(inside, hull, cv::Scalar(255));
    cv::Mat unknown = 255 - known;
    cv::Mat hole;
    cv::bitwise_and(inside, unknown, hole);
    // The hull's own outline pixels can be empty between two rim samples: only interior.
    cv::Mat eroded;
    cv::erode(inside, eroded, cv::Mat::ones(3, 3, CV_8U));
    cv::bitwise_and(hole, eroded, hole);
    // Scattered empty pixels among known ones (sampling gaps on steep or rough tops) are not
    // the crown: components smaller than min_component or than top_component x the largest
    // one are left to §11.
    cv::Mat labels;
    {
        cv::Mat stats, centroids;
        const int n = cv::connectedComponentsWithStats(hole, labels, stats, centroids, 8, CV_32S);
        int largest = 0;
        for (int l = 1; l < n; ++l) largest = std::max(largest, stats.at<int>(l, cv::CC_STAT_AREA));
        const double keep =
            std::max<double>(options.min_component, options.top_component * largest);
        int dropped = 0;
        for (int r = 0; r < rows; ++r)
            for (int c = 0; c < cols; ++c) {
                const int l = labels.at<int>(r, c);
                if (l > 0 && stats.at<int>(l, cv::CC_STAT_AREA) < keep) {
                    hole.at<std::uint8_t>(r, c) = 0;
                    ++dropped;
                }
            }
        info["components"] = n - 1;
        info["skipped_small_pixels"] = dropped;
    }
    const int hole_pixels = cv::countNonZero(hole);
    info["hole_pixels"] = hole_pixels;
    if (hole_pixels == 0) return finish();
    // Step 4: Telea on height and colour (every unknown pixel, so none is a known zero).
    height.setTo(0.0f, unknown);
    telea(height, unknown, options.telea_radius);
    telea(color, unknown, options.telea_radius);
    info["colour"] = inpaint_colour(color, hole, known, options);
    if (options.biharmonic) info["biharmonic"] = biharmonic(height, hole);
    if (!report_progress(progress, 0.4)) throw AlgorithmError("cancelled");
    if (options.ellipsoid) {
        // Axis-aligned ellipsoid A u^2 + B v^2 + C h^2 + D u + E v + F h = 1 (least squares,
        // coordinates centred and scaled for conditioning).
        Eigen::Vector3d mean = Eigen::Vector3d::Zero();
        for (const auto& t : top) mean += t;
        mean /= double(top.size());
        double scale = 0;
        for (const auto& t : top) scale = std::max(scale, (t - mean).cwiseAbs().maxCoeff());
        Eigen::Matrix<double, 6, 6> ata = Eigen::Matrix<double, 6, 6>::Zero();
        Eigen::Matrix<double, 6, 1> atb = Eigen::Matrix<double, 6, 1>::Zero();
        for (const auto& t : top) {
            const Eigen::Vector3d q = (t - mean) / scale;
            Eigen::Matrix<double, 6, 1> row;
            row << q.x() * q.x(), q.y() * q.y(), q.z() * q.z(), q.x(), q.y(), q.z();
            ata += row * row.transpose();
            atb += row;
        }
        const Eigen::Matrix<double, 6, 1> k = ata.ldlt().solve(atb);
        bool valid = k.allFinite() && k[0] > 0 && k[1] > 0 && k[2] > 0;
        // Fit residual, geometric to first order (|f| / |grad f|), in spacings: a top that is
        // not an ellipsoid (a wreath, a hat) is left open (or keeps the inpainted heights with
        // top_without_ellipsoid).
        double sq = 0;
        for (const auto& t : top) {
            const Eigen::Vector3d q = (t - mean) / scale;
            const double f = k[0] * q.x() * q.x() + k[1] * q.y() * q.y() + k[2] * q.z() * q.z() +
                             k[3] * q.x() + k[4] * q.y() + k[5] * q.z() - 1;
            const Eigen::Vector3d g(2 * k[0] * q.x() + k[3], 2 * k[1] * q.y() + k[4],
                                    2 * k[2] * q.z() + k[5]);
            const double d = scale * std::abs(f) / std::max(g.norm(), 1e-12);
            sq += d * d;
        }
        const double rms = std::sqrt(sq / double(top.size())) / spacing_m;
        info["ellipsoid_rms_spacings"] = rms;
        valid = valid && rms <= options.max_ellipsoid_rms;
        info["ellipsoid"] = valid;
        if (!valid && !options.top_without_ellipsoid) {
            // Not an ellipsoid (a wreath, a hat): nothing trustworthy to continue; the crown
            // stays open rather than invented.
            info["hole_pixels_left_open"] = hole_pixels;
            return finish();
        }
        if (valid) {
            // Centre and semi-axes (normalised units), for the report.
            const Eigen::Vector3d c(-k[3] / (2 * k[0]), -k[4] / (2 * k[1]), -k[5] / (2 * k[2]));
            const double g = 1 + k[0] * c.x() * c.x() + k[1] * c.y() * c.y() + k[2] * c.z() * c.z();
            if (g > 0)
                info["ellipsoid_semi_axes_m"] = {scale * std::sqrt(g / k[0]),
                                                 scale * std::sqrt(g / k[1]),
                                                 scale * std::sqrt(g / k[2])};
            // The ellipsoid's height per pixel (NaN where its upper sheet does not reach).
            const auto ellipsoid_height = [&](int r, int c2) {
                const double u = (ou + (c2 + 0.5) * px - mean.x()) / scale;
                const double v = (ov + (r + 0.5) * px - mean.y()) / scale;
                // C h^2 + F h + (A u^2 + B v^2 + D u + E v - 1) = 0, upper root.
                const double cc = k[0] * u * u + k[1] * v * v + k[3] * u + k[4] * v - 1;
                const double disc = k[5] * k[5] - 4 * k[2] * cc;
                if (disc < 0) return std::numeric_limits<double>::quiet_NaN();
                return (-k[5] + std::sqrt(disc)) / (2 * k[2]) * scale + mean.z();
            };
            // [M] The ellipsoid gives the crown's shape, the measured rim its place: the
            // residual (measured height - ellipsoid) of the known pixels is carried into the
            // hole by a harmonic solve (each hole pixel a smooth average of the rim's
            // residuals), and the crown is ellipsoid + residual. The surface meets the rim
            // without a step and the ellipsoid's misfit at the rim (a head is no ellipsoid;
            // the fit runs a few mm high or low there) corrects its interior too.
            cv::Mat residual(rows, cols, CV_32F, cv::Scalar(0.0f));
            cv::Mat no_residual(rows, cols, CV_8U, cv::Scalar(255));
            cv::Mat surface(rows, cols, CV_32F,
                            cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
            for (int r = 0; r < rows; ++r)
                for (int c2 = 0; c2 < cols; ++c2) {
                    const double h = ellipsoid_height(r, c2);
                    surface.at<float>(r, c2) = static_cast<float>(h);
                    if (!known.at<std::uint8_t>(r, c2) || !std::isfinite(h)) continue;
                    residual.at<float>(r, c2) = static_cast<float>(
                        outer_sum.at<double>(r, c2) / outer_count.at<int>(r, c2) - h);
                    no_residual.at<std::uint8_t>(r, c2) = 0;
                }
            // The rim's residuals are the sensors' noise at grazing angles plus the largest
            // height per pixel: a masked 5 x 5 median keeps the shape and drops the noise.
            {
                const cv::Mat raw = residual.clone();
                std::vector<float> window;
                for (int r = 0; r < rows; ++r)
                    for (int c2 = 0; c2 < cols; ++c2) {
                        if (no_residual.at<std::uint8_t>(r, c2)) continue;
                        window.clear();
                        for (int dr = -2; dr <= 2; ++dr)
                            for (int dc = -2; dc <= 2; ++dc) {
                                const int r2 = r + dr, c3 = c2 + dc;
                                if (r2 < 0 || c3 < 0 || r2 >= rows || c3 >= cols ||
                                    no_residual.at<std::uint8_t>(r2, c3))
                                    continue;
                                window.push_back(raw.at<float>(r2, c3));
                            }
                        std::nth_element(window.begin(), window.begin() + window.size() / 2,
                                         window.end());
                        residual.at<float>(r, c2) = window[window.size() / 2];
                    }
            }
            telea(residual, no_residual, options.telea_radius);
            info["residual_harmonic"] = biharmonic(residual, hole, /*harmonic=*/true);
            // Every pixel the ellipsoid reaches takes ellipsoid + residual, the known ones too:
            // only hole pixels become points, but their positions and normals interpolate
            // their neighbours, which are then the smoothed rim, not its noisiest samples.
            int used = 0;
            for (int r = 0; r < rows; ++r)
                for (int c2 = 0; c2 < cols; ++c2) {
                    const float h = surface.at<float>(r, c2);
                    if (!std::isfinite(h)) continue;  // keeps the inpainted height
                    height.at<float>(r, c2) = h + residual.at<float>(r, c2);
                    used += hole.at<std::uint8_t>(r, c2) ? 1 : 0;
                }
            info["ellipsoid_pixels"] = used;
        }
    }
    if (!report_progress(progress, 0.7)) throw AlgorithmError("cancelled");
    // Step 5: back-projection of the hole pixels at the step, normals from the gradient.
    const int n_sub = std::max(1, static_cast<int>(std::lround(options.pixel / options.step)));
    Candidates cand;
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            if (!hole.at<std::uint8_t>(r, c)) continue;
            const int cl = std::max(c - 1, 0), cr = std::min(c + 1, cols - 1);
            const int rl = std::max(r - 1, 0), rr = std::min(r + 1, rows - 1);
            const double hu =
                (height.at<float>(r, cr) - height.at<float>(r, cl)) / (std::max(cr - cl, 1) * px);
            const double hv =
                (height.at<float>(rr, c) - height.at<float>(rl, c)) / (std::max(rr - rl, 1) * px);
            const Eigen::Vector3d n = (up - hu * e1 - hv * e2).normalized();
            for (int a = 0; a < n_sub; ++a)
                for (int b = 0; b < n_sub; ++b) {
                    const double fc = c + (a + 0.5) / n_sub - 0.5;  // pixel-centre coordinates
                    const double fr = r + (b + 0.5) / n_sub - 0.5;
                    const double h = bilinear(height, fr, fc, false);
                    const double u = ou + (fc + 0.5) * px, v = ov + (fr + 0.5) * px;
                    cand.push(axis.origin + u * e1 + v * e2 + h * up, n, pixel_rgb(color, r, c),
                              static_cast<std::uint32_t>(labels.at<int>(r, c)));
                }
        }
    keep_candidates(cand, points, sensors, spacing_m, options, FillMechanism::kHeadTop, result,
                    info);
    if (!report_progress(progress, 1.0)) throw AlgorithmError("cancelled");
    return finish();
}

}  // namespace rgbd::holes
