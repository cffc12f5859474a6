#include "algorithms/denoise/depth_smoothing.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "algorithms/denoise/outlier_common.hpp"
#include "toolkit/error.hpp"

namespace rgbd::denoise {

void SmoothOptions::check() const {
    check_range("depth smoothing: half_window", half_window, Range::closed(1, 7));
    check_range("depth smoothing: gate_sigmas", gate_sigmas, Range::open_closed(0.0, 100.0));
    const int side = 2 * half_window + 1;
    check_range("depth smoothing: min_support", min_support, Range::closed(1, side * side));
}

Report smooth_depth(PointCloud& cloud, const SmoothOptions& options, const Progress& progress) {
    Stopwatch watch;
    Report report;
    const detail::Gathered g = detail::open_run(cloud, options, "smooth", report);
    const std::size_t n = g.xyz.size();
    const std::string name = detail::view_name(cloud);
    if (n == 0) {
        report["moved"] = 0;
        report["time_s"] = watch.seconds();
        return report;
    }
    const auto pixel = detail::organised_pixels(
        cloud, name,
        "--smooth works on organised views (pixel grid), before alignment; this view has none",
        "--smooth needs the `pixel` property of an organised view (straight from rgbd-cloud)");
    Pose sensor_from_frame = Pose::Identity();
    if (cloud.view.frame == ViewFrame::kWorld)
        sensor_from_frame = detail::sensor_from_world(cloud, name, "--smooth");
    if (!report_progress(progress, 0.0)) return detail::cancelled(report, watch);

    // Depth grid of the live, unflagged points in front of the sensor (first point per pixel).
    const int width = cloud.view.grid_width, height = cloud.view.grid_height;
    const std::size_t cells = std::size_t(width) * std::size_t(height);
    std::vector<float> depth(cells, 0.0f);  // 0 = no usable pixel
    std::vector<std::int32_t> at(n, -1);    // pixel of point i, -1 = not smoothed
    const auto noise = cloud.flag(prop::kNoise);
    for (std::size_t i = 0; i < n; ++i) {
        if (noise && (*noise)[g.ids[i]]) continue;
        const std::uint32_t px = pixel[g.ids[i]];
        const double z = (sensor_from_frame * g.xyz[i]).z();
        if (px >= cells || !(z > 0.0) || depth[px] > 0.0f) continue;
        depth[px] = float(z);
        at[i] = std::int32_t(px);
    }

    // New depth per pixel (0 = unchanged), rows in parallel; no allocation inside.
    std::vector<float> smoothed(cells, 0.0f);
    const int h = options.half_window;
    tbb::parallel_for(tbb::blocked_range<int>(0, height, 8), [&](const tbb::blocked_range<int>& r) {
        // The window's valid pixels: inverse depth and offsets (at most 15 x 15).
        double inv[225];
        int ou[225], ov[225];
        const auto at_pixel = [&](int rr, int cc) {
            return rr < 0 || rr >= height || cc < 0 || cc >= width
                       ? 0.0
                       : double(depth[std::size_t(rr) * width + cc]);
        };
        // Inverse-depth slope from the centre to one side, or to the other (the smaller step:
        // the larger one may cross an edge); 0 without neighbours.
        const auto slope = [](double w, double before, double after) {
            const double a = before > 0.0 ? w - 1.0 / before : 0.0;
            const double b = after > 0.0 ? 1.0 / after - w : 0.0;
            if (before <= 0.0) return b;
            if (after <= 0.0) return a;
            return std::abs(a) < std::abs(b) ? a : b;
        };
        for (int row = r.begin(); row != r.end(); ++row)
            for (int col = 0; col < width; ++col) {
                const double z = depth[std::size_t(row) * width + col];
                if (z <= 0.0) continue;
                const double gate = options.gate_sigmas * sigma_z_m(options.noise_model, z);
                const double gate_inv = gate / (z * z);
                int m = 0;
                for (int dv = -h; dv <= h; ++dv)
                    for (int du = -h; du <= h; ++du) {
                        const double zj = at_pixel(row + dv, col + du);
                        if (zj <= 0.0) continue;
                        inv[m] = 1.0 / zj;
                        ou[m] = du;
                        ov[m] = dv;
                        ++m;
                    }
                if (m < options.min_support) continue;
                // Plane 1/z = a + b du + c dv: starts through the point with the one-sided
                // slopes, then twice: the pixels within the gate of the current plane (the
                // same surface, whatever its slope) are fitted by least squares.
                const double w = 1.0 / z;
                double a = w, b = slope(w, at_pixel(row, col - 1), at_pixel(row, col + 1)),
                       c = slope(w, at_pixel(row - 1, col), at_pixel(row + 1, col));
                bool ok = true;
                for (int pass = 0; pass < 2 && ok; ++pass) {
                    double s = 0, su = 0, sv = 0, suu = 0, svv = 0, suv = 0, b0 = 0, bu = 0, bv = 0;
                    for (int q = 0; q < m; ++q) {
                        // |z_q - 1 / plane| <= gate, to first order in inverse depth
                        // (gate << z): no division, no branch (0 / 1 weight).
                        const double in =
                            std::abs(inv[q] - (a + b * ou[q] + c * ov[q])) <= gate_inv ? 1.0 : 0.0;
                        const double u = in * ou[q], v = in * ov[q], iw = in * inv[q];
                        s += in;
                        su += u;
                        sv += v;
                        suu += u * ou[q];
                        svv += v * ov[q];
                        suv += u * ov[q];
                        b0 += iw;
                        bu += iw * ou[q];
                        bv += iw * ov[q];
                    }
                    if (s < options.min_support) {
                        ok = false;
                        break;
                    }
                    // Normal equations [s su sv; su suu suv; sv suv svv] x = (b0, bu, bv),
                    // solved by cofactors. det / s^3 is scale-free; integer offsets on one line
                    // give exactly 0: then the slopes stay and only the offset is fitted.
                    const double c00 = suu * svv - suv * suv, c01 = suv * sv - su * svv,
                                 c02 = su * suv - suu * sv;
                    const double det = s * c00 + su * c01 + sv * c02;
                    if (det > 1e-3 * s * s * s) {
                        const double c11 = s * svv - sv * sv, c12 = su * sv - s * suv,
                                     c22 = s * suu - su * su;
                        a = (c00 * b0 + c01 * bu + c02 * bv) / det;
                        b = (c01 * b0 + c11 * bu + c12 * bv) / det;
                        c = (c02 * b0 + c12 * bu + c22 * bv) / det;
                    } else {
                        a = (b0 - b * su - c * sv) / s;
                    }
                }
                if (!ok || !(a > 0.0)) continue;
                const double zn = 1.0 / a;
                if (!std::isfinite(zn) || std::abs(zn - z) > gate) continue;
                smoothed[std::size_t(row) * width + col] = float(zn);
            }
    });
    if (!report_progress(progress, 0.8)) return detail::cancelled(report, watch);

    // Move each point along its ray: scale about the camera centre of its frame.
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    if (cloud.view.frame == ViewFrame::kWorld) centre = cloud.view.world_from_sensor->translation();
    std::size_t moved = 0;
    double shift = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        if (at[i] < 0) continue;
        const float zn = smoothed[std::size_t(at[i])];
        if (zn <= 0.0f) continue;
        const double z = depth[std::size_t(at[i])];
        const double scale = double(zn) / z;
        cloud.points.point(g.ids[i]) = to_point(centre + scale * (g.xyz[i] - centre));
        ++moved;
        shift += std::abs(double(zn) - z);
    }
    report["moved"] = moved;
    report["unchanged"] = n - moved;
    report["mean_shift_mm"] = moved > 0 ? 1000.0 * shift / double(moved) : 0.0;
    return detail::finished(std::move(report), watch, progress);
}

}  // namespace rgbd::denoise
