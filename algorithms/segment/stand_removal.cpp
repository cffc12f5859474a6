#include "algorithms/segment/stand_removal.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "algorithms/denoise/outlier_common.hpp"
#include "algorithms/internal/plane_fit.hpp"
#include "toolkit/error.hpp"
#include "toolkit/order_statistics.hpp"
#include "toolkit/random.hpp"
#include "toolkit/synthetic_view.hpp"

namespace rgbd::segment {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

/// World coordinates of a view's live points (same order as detail::gather's ids).
std::vector<Eigen::Vector3d> world_points(const PointCloud& view,
                                          const denoise::detail::Gathered& g) {
    std::vector<Eigen::Vector3d> out = g.xyz;
    if (view.view.frame == ViewFrame::kSensor) {
        RGBD_CHECK(view.view.world_from_sensor.has_value(),
                   denoise::detail::view_name(view) + " is in its sensor frame without a pose");
        const Pose& pose = *view.view.world_from_sensor;
        for (auto& p : out) p = pose * p;
    }
    return out;
}

/// internal::fit_plane into a SupportPlane.
bool fit_plane(const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& up,
               SupportPlane& plane) {
    return internal::fit_plane(points, up, plane.normal, plane.offset);
}

}  // namespace

void StandOptions::check() const {
    check_range("stand: max tilt", max_tilt_deg, Range::open(0, 90), "deg");
    check_range("stand: inlier distance", inlier_m, Range::open(0, 1), "m");
    check_range("stand: margin", margin_m, Range::closed_open(0, 1), "m");
    check_range("stand: search fraction", search_fraction, Range::open_closed(0, 1));
    check_range("stand: min support", min_support, Range::open(0, 1));
    check_range("stand: min above", min_above, Range::closed_open(0, 1));
    check_range("stand: contact band", contact_band_m, Range::closed_open(0, 1), "m");
    RGBD_CHECK(iterations >= 1 && max_samples >= 3, "stand: iterations >= 1, samples >= 3");
}

std::optional<Eigen::Vector3d> cameras_up(const std::vector<PointCloud>& views) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    int n = 0;
    for (const auto& v : views) {
        if (!v.view.world_from_sensor) continue;
        sum -= v.view.world_from_sensor->linear().col(1);
        ++n;
    }
    if (n == 0 || sum.norm() < 1e-6 * n) return std::nullopt;
    return sum.normalized();
}

std::optional<SupportPlane> find_support_plane(const std::vector<PointCloud>& views,
                                               const Eigen::Vector3d& up_in,
                                               const StandOptions& options) {
    options.check();
    RGBD_CHECK(up_in.allFinite() && up_in.norm() > 0, "stand: up direction must be non-zero");
    const Eigen::Vector3d up = up_in.normalized();
    std::vector<Eigen::Vector3d> all;
    for (const auto& v : views) {
        const auto pts = world_points(v, denoise::detail::gather(v));
        all.insert(all.end(), pts.begin(), pts.end());
    }
    if (all.size() < 100) return std::nullopt;
    // Heights along up; the search band is the lowest part of the robust height range.
    std::vector<double> h(all.size());
    tbb::parallel_for(std::size_t(0), all.size(), [&](std::size_t i) { h[i] = all[i].dot(up); });
    std::vector<double> sorted = h;
    const double lo = rank_quantile(sorted, 0.02), hi = rank_quantile(sorted, 0.98);
    const double band = lo + options.search_fraction * (hi - lo);
    std::vector<Eigen::Vector3d> low;
    const std::size_t stride =
        std::max<std::size_t>(1, all.size() / static_cast<std::size_t>(options.max_samples));
    for (std::size_t i = 0; i < all.size(); i += stride)
        if (h[i] <= band) low.push_back(all[i]);
    if (low.size() < 3) return std::nullopt;

    // RANSAC: planes through 3 low points whose normal is within max_tilt of up; the score is
    // the number of low samples within inlier_m.
    const double cos_tilt = std::cos(options.max_tilt_deg * kDeg);
    SupportPlane best;
    const std::size_t best_score =
        internal::ransac_plane(low, up, cos_tilt, options.inlier_m, options.iterations,
                               options.seed, best.normal, best.offset);
    if (best_score < 3) return std::nullopt;
    // Refine twice by least squares on the inliers of all points.
    for (int round = 0; round < 2; ++round) {
        std::vector<Eigen::Vector3d> in;
        for (const auto& p : all)
            if (std::abs(best.normal.dot(p) + best.offset) <= options.inlier_m) in.push_back(p);
        SupportPlane refined;
        if (!fit_plane(in, up, refined) || refined.normal.dot(up) < cos_tilt) break;
        best.normal = refined.normal;
        best.offset = refined.offset;
    }
    std::size_t inliers = 0, above = 0;
    const double above_m = 10.0 * std::max(options.margin_m, options.inlier_m);
    for (const auto& p : all) {
        const double s = best.normal.dot(p) + best.offset;
        inliers += std::abs(s) <= options.inlier_m;
        above += s > above_m;
    }
    best.inliers = inliers;
    const double n = static_cast<double>(all.size());
    if (inliers < options.min_support * n || above < options.min_above * n) return std::nullopt;
    return best;
}

PointCloud contact_points(const std::vector<PointCloud>& views, const SupportPlane& plane,
                          const StandOptions& options) {
    options.check();
    int max_id = -1;
    for (const auto& v : views) max_id = std::max(max_id, v.view.id);
    PointCloud out = synthetic_world_view(max_id + 1, "rgbd-stand");
    const auto colors = out.colors();
    const auto synthetic = *out.flag(prop::kSynthetic);
    const double cos60 = 0.5;
    for (const auto& v : views) {
        const auto g = denoise::detail::gather(v);
        const auto pts = world_points(v, g);
        const bool has_normals = v.points.has_normal_map();
        const bool has_colors = v.has_colors();
        Eigen::Matrix3d rot = Eigen::Matrix3d::Identity();
        if (v.view.frame == ViewFrame::kSensor) rot = v.view.world_from_sensor->linear();
        for (std::size_t i = 0; i < pts.size(); ++i) {
            const double h = plane.normal.dot(pts[i]) + plane.offset;
            if (h < options.margin_m || h >= options.margin_m + options.contact_band_m) continue;
            Eigen::Vector3d n = Eigen::Vector3d::Zero();
            if (has_normals) {
                const Vector_3 nv = v.points.normal(g.ids[i]);
                n = rot * Eigen::Vector3d(nv.x(), nv.y(), nv.z());
                if (n.norm() > 0) n.normalize();
                if (std::abs(n.dot(plane.normal)) > cos60) continue;  // not a wall
            }
            for (const double f : {0.0, 1.0 / 3.0, 2.0 / 3.0}) {
                const Eigen::Vector3d q = pts[i] - (h - f * options.margin_m) * plane.normal;
                const auto idx = *out.points.insert(to_point(q));
                out.points.normal(idx) = Vector_3(n.x(), n.y(), n.z());
                if (has_colors) colors.set(idx, v.colors().get(g.ids[i]));
                synthetic[idx] = 1;
            }
        }
    }
    return out;
}

Report remove_stand(std::vector<PointCloud>& views, const StandOptions& options,
                    const Progress& progress, std::optional<SupportPlane>* plane_out) {
    const Stopwatch watch;
    if (plane_out) plane_out->reset();
    Report report = {{"found", false}, {"removed", 0}};
    const auto up = cameras_up(views);
    if (!up) {
        report["note"] = "stand: no view has a pose; nothing removed";
        report["time_s"] = watch.seconds();
        return report;
    }
    report["cameras_up"] = {up->x(), up->y(), up->z()};
    const auto plane = find_support_plane(views, *up, options);
    report_progress(progress, 0.5);
    if (!plane) {
        report["note"] = "stand: no support plane below the object; nothing removed";
        report["time_s"] = watch.seconds();
        return report;
    }
    report["found"] = true;
    if (plane_out) *plane_out = plane;
    report["plane"] = {{"normal", {plane->normal.x(), plane->normal.y(), plane->normal.z()}},
                       {"offset_m", plane->offset},
                       {"inliers", plane->inliers}};
    report["tilt_deg"] = std::acos(std::clamp(plane->normal.dot(*up), -1.0, 1.0)) / kDeg;
    std::vector<std::size_t> removed(views.size(), 0);
    tbb::parallel_for(std::size_t(0), views.size(), [&](std::size_t v) {
        const auto g = denoise::detail::gather(views[v]);
        const auto pts = world_points(views[v], g);
        std::vector<std::uint8_t> out(pts.size(), 0);
        for (std::size_t i = 0; i < pts.size(); ++i)
            out[i] = plane->normal.dot(pts[i]) + plane->offset < options.margin_m;
        removed[v] = denoise::detail::apply(views[v], g, out, false);
    });
    std::size_t total = 0;
    Report per_view = Report::array();
    for (std::size_t v = 0; v < views.size(); ++v) {
        total += removed[v];
        per_view.push_back({{"view", views[v].view.id}, {"removed", removed[v]}});
    }
    report["removed"] = total;
    report["views"] = per_view;
    report_progress(progress, 1.0);
    report["time_s"] = watch.seconds();
    return report;
}

}  // namespace rgbd::segment
