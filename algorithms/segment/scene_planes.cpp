#include "algorithms/segment/scene_planes.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>
#include <string>

#include "algorithms/segment/ground_plane.hpp"
#include "algorithms/segment/stand_removal.hpp"
#include "toolkit/order_statistics.hpp"

namespace rgbd::segment::detail {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

/// The metadata line that carries a view's ground plane (kGroundKey).
std::string plane_line(const ViewGround& g) {
    std::ostringstream s;
    s.precision(17);
    s << kGroundKey << g.normal.x() << ' ' << g.normal.y() << ' ' << g.normal.z() << ' ' << g.offset
      << ' ' << g.margin_m;
    return s.str();
}

/// Every stride-th of the views' points (of those not removed, with `live_only`), in view and
/// point order, with its world position and grid normal: the planes' samples. The views run in
/// parallel (a grid normal is a small fit), each from its first point's rank in that order.
std::vector<GroundSample> strided_samples(const std::vector<ViewPoints>& vps,
                                          const std::vector<PointCloud>& views, std::size_t stride,
                                          bool live_only) {
    std::vector<std::size_t> first(vps.size() + 1, 0);  // rank of each view's first point
    for (std::size_t v = 0; v < vps.size(); ++v)
        first[v + 1] = first[v] + (live_only ? static_cast<std::size_t>(std::count(
                                                   vps[v].removed.begin(), vps[v].removed.end(), 0))
                                             : vps[v].world.size());
    std::vector<std::vector<GroundSample>> per_view(vps.size());
    tbb::parallel_for(std::size_t(0), vps.size(), [&](std::size_t v) {
        std::size_t k = first[v];
        for (std::size_t i = 0; i < vps[v].world.size(); ++i)
            if ((!live_only || !vps[v].removed[i]) && k++ % stride == 0)
                per_view[v].push_back(
                    {vps[v].world[i], vps[v].grid_normal(i, *views[v].view.world_from_sensor)});
    });
    std::vector<GroundSample> samples;
    samples.reserve(first.back() / stride + vps.size());
    for (const auto& s : per_view) samples.insert(samples.end(), s.begin(), s.end());
    return samples;
}

/// Every view's refit of the world-frame `plane` in its own sensor frame (refit_view_ground,
/// with its sensor's noise model and the seed `seed` + the view's index), in parallel.
std::vector<ViewGroundFit> refit_in_views(const Plane& plane, std::vector<ViewPoints>& vps,
                                          const std::vector<PointCloud>& views,
                                          const std::vector<denoise::NoiseModel>& noise,
                                          const SubjectOptions& o, std::uint64_t seed, bool wall) {
    std::vector<ViewGroundFit> fits(views.size());
    tbb::parallel_for(std::size_t(0), views.size(), [&](std::size_t v) {
        const Pose& pose = *views[v].view.world_from_sensor;
        const Plane in_sensor{pose.linear().transpose() * plane.n,
                              plane.d + plane.n.dot(pose.translation())};
        fits[v] = refit_view_ground(vps[v].g.xyz, in_sensor, vps[v].sensor_normals(),
                                    noise.size() == 1 ? noise[0] : noise[v], o, seed + v, wall);
    });
    return fits;
}

/// Every view's cut above its refit (cut_above_ground), in parallel: each marks its own points.
std::vector<GroundCut> cut_in_views(std::vector<ViewPoints>& vps,
                                    const std::vector<ViewGroundFit>& fits,
                                    const std::vector<denoise::NoiseModel>& noise,
                                    const SubjectOptions& o) {
    std::vector<GroundCut> cuts(vps.size());
    tbb::parallel_for(std::size_t(0), vps.size(), [&](std::size_t v) {
        cuts[v] = cut_above_ground(vps[v].g.xyz, fits[v], noise.size() == 1 ? noise[0] : noise[v],
                                   o, vps[v].removed);
    });
    return cuts;
}

}  // namespace

/// Step 1 (scene_planes.hpp).
Report remove_ground(std::vector<ViewPoints>& vps, std::vector<PointCloud>& views,
                     const std::vector<denoise::NoiseModel>& noise, const SubjectOptions& options,
                     std::size_t total) {
    Report ground = {{"found", false}};
    const auto up = cameras_up(views);
    if (!options.remove_ground) {
        ground["note"] = "kept (--keep-ground)";
        return ground;
    }
    if (!up) {
        ground["note"] = "no camera up (no poses)";
        return ground;
    }
    const std::size_t stride =
        std::max<std::size_t>(1, total / static_cast<std::size_t>(options.max_samples));
    const std::vector<GroundSample> samples = strided_samples(vps, views, stride, false);
    std::size_t inliers = 0;
    const auto plane = pooled_ground(samples, *up, options, inliers);
    if (!plane) {
        ground["note"] = "no ground plane in view";
        return ground;
    }
    // Each view refits the plane in its own frame (its pose may be centimetres off before
    // alignment). The plane is the ground when the views see it flat (half the views hold 50
    // points facing it, and the median of their robust deviations about it is at most
    // ground_flat_sigmas of the sensor's own depth noise at those points' depth and incidence:
    // not the curved bottom of an object standing on nothing) and as the lowest large surface (at
    // most 15% of the points more than half a band below it, and fewer below than above it: a cap
    // or a ring of an object's surface has its object below it).
    const std::vector<ViewGroundFit> fits =
        refit_in_views(*plane, vps, views, noise, options, options.seed + 2, false);
    std::vector<double> fitted, flatness;
    std::size_t below = 0, above = 0, points = 0;
    for (std::size_t v = 0; v < views.size(); ++v) {
        if (fits[v].facing > 0) flatness.push_back(fits[v].normalized);
        if (fits[v].rms_m > 0) fitted.push_back(fits[v].rms_m);
        below += fits[v].below, above += fits[v].above, points += fits[v].points;
    }
    const double median_rms = fitted.empty() ? 0.0 : rank_quantile(fitted, 0.5);
    const double median_flatness = flatness.empty() ? 0.0 : rank_quantile(flatness, 0.5);
    ground["fit_rms_m"] = median_rms;
    ground["flatness_sigmas"] = median_flatness;
    ground["flat_views"] = flatness.size();
    ground["below_share"] = points ? double(below) / double(points) : 0.0;
    ground["above_share"] = points ? double(above) / double(points) : 0.0;
    ground["normal"] = {plane->n.x(), plane->n.y(), plane->n.z()};
    ground["offset_m"] = plane->d;
    ground["sample_inliers"] = inliers;
    ground["tilt_deg"] = std::acos(std::clamp(plane->n.dot(*up), -1.0, 1.0)) / kDeg;
    const double n = static_cast<double>(points);
    if (flatness.size() * 2 < views.size()) {
        ground["note"] =
            "the lowest plane facing up is not seen facing up in half the views "
            "(too few points on it face it): no ground";
        return ground;
    }
    if (median_flatness > options.ground_flat_sigmas) {
        ground["note"] = "the lowest plane facing up is not flat (median robust deviation " +
                         std::to_string(median_flatness) + " sigma_z, " +
                         std::to_string(median_rms * 1000.0) + " mm): no ground";
        return ground;
    }
    if (below > 0.15 * n || (below > above && below + above > 0.1 * n)) {
        ground["note"] = "the lowest plane facing up has much of the scene below it: no ground";
        return ground;
    }
    ground["found"] = true;
    Report per_view = Report::array();
    std::size_t removed = 0;
    const std::vector<GroundCut> cuts = cut_in_views(vps, fits, noise, options);
    for (std::size_t v = 0; v < views.size(); ++v) {
        const GroundCut& cut = cuts[v];
        ViewGround g;
        g.normal = fits[v].plane.n;
        g.offset = fits[v].plane.d;
        g.margin_m = cut.margin_m;
        removed += cut.cut;
        auto& comments = views[v].view.extra_comments;
        comments.erase(
            std::remove_if(comments.begin(), comments.end(),
                           [](const std::string& c) { return c.rfind(kGroundKey, 0) == 0; }),
            comments.end());
        comments.push_back(plane_line(g));
        per_view.push_back({{"view", views[v].view.id},
                            {"removed", cut.cut},
                            {"margin_m", g.margin_m},
                            {"rms_m", fits[v].rms_m},
                            {"facing", fits[v].facing},
                            {"flatness_sigmas", fits[v].normalized}});
    }
    ground["removed"] = removed;
    ground["views"] = per_view;
    return ground;
}

namespace {

/// What judge_wall decided.
enum class WallVerdict { kWall, kSensorsOnBothSides, kNotFlat, kSeenThrough };

/// The tests a wall candidate passes after the pooled one (scene_planes.hpp, step 1b): every
/// sensor in front of it, flat in half the views, nothing seen through it in the views' median;
/// a wall is cut in every view. Fills `wall` (found, note, the views' figures).
WallVerdict judge_wall(const Plane& plane, std::vector<ViewPoints>& vps,
                       const std::vector<PointCloud>& views,
                       const std::vector<denoise::NoiseModel>& noise, const SubjectOptions& o,
                       double flat_bound, std::uint64_t seed, Report& wall) {
    // Sensors on both sides first (cheap); the views' refits only for a candidate wall. A
    // sensor within half the ground band of the plane sees it edge-on and tells neither side
    // (the APC shelf's arm takes one view 3 mm off a side wall's plane).
    bool in_front = true;
    for (const auto& view : views)
        in_front = in_front && plane.height(view.view.world_from_sensor->translation()) >
                                   -0.5 * o.ground_band_m;
    if (!in_front) {
        wall["note"] = "sensors on both sides";
        return WallVerdict::kSensorsOnBothSides;
    }
    const std::vector<ViewGroundFit> fits = refit_in_views(plane, vps, views, noise, o, seed, true);
    std::vector<double> flatness, behind_view, through_view;
    for (std::size_t v = 0; v < views.size(); ++v) {
        if (fits[v].facing == 0 || fits[v].points == 0) continue;  // not seen
        flatness.push_back(fits[v].normalized);
        behind_view.push_back(double(fits[v].below) / double(fits[v].points));
        through_view.push_back(double(fits[v].through) / double(fits[v].points));
    }
    const auto median = [](std::vector<double>& x) {
        return x.empty() ? 0.0 : rank_quantile(x, 0.5);
    };
    const double flat = median(flatness), through = median(through_view);
    wall["flatness_sigmas"] = flat;
    wall["flatness_bound_sigmas"] = flat_bound;
    wall["flat_views"] = flatness.size();
    wall["view_behind_share"] = median(behind_view);
    wall["view_through_share"] = through;
    if (flatness.size() * 2 < views.size() || flat > flat_bound) {
        wall["note"] = "not flat in half the views";
        return WallVerdict::kNotFlat;
    }
    // Nothing seen through it in each view's own refit either: a plane through a face of what
    // leans on a wall (a box at 11-15 degrees on the APC shelf's side wall) has the wall in the
    // wedge behind it, seen where the plane's surface would hide it (the views' median
    // 1.7-6.5% of their points; the walls 0.00-0.04%). Points behind a wall's plane beyond its
    // extent (the shelf's front lip, 3.5 cm behind a side wall's plane) do not count.
    if (through > o.wall_max_through_share) {
        wall["note"] = "seen through in the views";
        return WallVerdict::kSeenThrough;
    }
    std::size_t removed = 0;
    std::vector<double> margins;
    for (const GroundCut& cut : cut_in_views(vps, fits, noise, o)) {
        removed += cut.cut;
        margins.push_back(cut.margin_m);
    }
    wall["margin_m"] = median(margins);
    wall["found"] = true;
    wall["removed"] = removed;
    return WallVerdict::kWall;
}

/// The report of a candidate after the pooled test.
Report wall_entry(const Plane& plane, std::size_t inliers, std::size_t behind,
                  std::size_t samples) {
    return {{"normal", {plane.n.x(), plane.n.y(), plane.n.z()}},
            {"offset_m", plane.d},
            {"sample_inliers", inliers},
            {"behind_share", double(behind) / double(samples)},
            {"found", false}};
}

}  // namespace

/// Step 1b (scene_planes.hpp).
Report remove_walls(std::vector<ViewPoints>& vps, const std::vector<PointCloud>& views,
                    const std::vector<denoise::NoiseModel>& noise, const SubjectOptions& o,
                    double ground_flatness) {
    const double flat_bound = o.ground_flat_sigmas * std::max(1.0, ground_flatness);
    Report walls = Report::array();
    std::size_t total = 0;
    for (const auto& vp : vps)
        for (auto r : vp.removed) total += !r;
    if (!o.remove_walls || total == 0) return walls;
    const std::size_t stride =
        std::max<std::size_t>(1, total / static_cast<std::size_t>(o.max_samples));
    const std::vector<GroundSample> samples = strided_samples(vps, views, stride, true);
    Eigen::Vector3d cameras = Eigen::Vector3d::Zero();
    for (const auto& v : views) cameras += v.view.world_from_sensor->translation();
    cameras /= static_cast<double>(views.size());
    std::vector<std::uint8_t> used(samples.size(), 0);
    // The samples of the candidates refused as not flat or seen through: slices through a
    // wall and what leans on it, searched again below with a narrower cone.
    std::vector<std::uint8_t> refused(samples.size(), 0);
    const auto search = [&](const SubjectOptions& cone, int rounds, std::uint64_t seed) {
        for (int round = 0; round < rounds; ++round) {
            std::size_t inliers = 0, behind = 0;
            const std::vector<std::uint8_t> used_before = used;
            const auto plane =
                pooled_bounding_plane(samples, used, cameras, cone, seed + round, inliers, behind);
            if (!plane) break;
            Report wall = wall_entry(*plane, inliers, behind, samples.size());
            if (behind > o.wall_max_behind_share * samples.size()) {
                wall["note"] = "points behind it";
            } else {
                const WallVerdict verdict =
                    judge_wall(*plane, vps, views, noise, o, flat_bound, o.seed + 200, wall);
                if (verdict == WallVerdict::kNotFlat || verdict == WallVerdict::kSeenThrough)
                    for (std::size_t i = 0; i < samples.size(); ++i)
                        refused[i] |= used[i] && !used_before[i];
            }
            walls.push_back(wall);
        }
    };
    search(o, 6, o.seed + 100);
    // Second pass: the refused slices' samples, with wall_split_tilt_deg: the wall's own
    // plane is proposed there once the box leaning on it no longer shares its votes.
    if (std::find(refused.begin(), refused.end(), 1) != refused.end()) {
        for (std::size_t i = 0; i < samples.size(); ++i)
            if (refused[i]) used[i] = 0;
        SubjectOptions narrow = o;
        narrow.ground_max_tilt_deg = o.wall_split_tilt_deg;
        const std::size_t first_split = walls.size();
        search(narrow, 4, o.seed + 300);
        for (std::size_t w = first_split; w < walls.size(); ++w) walls[w]["second_pass"] = true;
    }
    return walls;
}

}  // namespace rgbd::segment::detail
