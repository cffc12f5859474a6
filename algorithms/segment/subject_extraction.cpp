#include "algorithms/segment/subject_extraction.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <unordered_map>

#include "algorithms/denoise/outlier_common.hpp"
#include "algorithms/segment/ground_plane.hpp"
#include "algorithms/segment/scene_planes.hpp"
#include "toolkit/error.hpp"
#include "toolkit/order_statistics.hpp"

namespace rgbd::segment {
namespace {

using detail::ViewPoints;

/// Packs integer voxel coordinates into one key (21 bits each, offset).
std::int64_t voxel_key(const Eigen::Vector3i& c) {
    constexpr std::int64_t kOff = 1 << 20;
    return ((static_cast<std::int64_t>(c.x()) + kOff) << 42) |
           ((static_cast<std::int64_t>(c.y()) + kOff) << 21) |
           (static_cast<std::int64_t>(c.z()) + kOff);
}

/// Union-find over voxel indices.
struct Components {
    std::vector<int> parent;
    int find(int x) {
        while (parent[x] != x) x = parent[x] = parent[parent[x]];
        return x;
    }
    void unite(int a, int b) {
        a = find(a), b = find(b);
        if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
};

/// The connectivity voxel: 3 pixel footprints at the median depth of the live points in the
/// middle ninth of each image (where the sensors aim: the subject, not the far room around it).
double auto_voxel(const std::vector<ViewPoints>& vps, const std::vector<PointCloud>& views) {
    std::vector<double> footprint;
    for (std::size_t v = 0; v < views.size(); ++v) {
        const auto& intr = views[v].view.intrinsics;
        const double f = intr ? 0.5 * (intr->fx + intr->fy) : 500.0;
        const auto& xyz = vps[v].g.xyz;
        for (std::size_t i = 0; i < xyz.size(); ++i) {
            if (vps[v].removed[i] || !(xyz[i].z() > 0)) continue;
            if (intr) {
                const double u = intr->fx * xyz[i].x() / xyz[i].z() + intr->cx;
                const double w = intr->fy * xyz[i].y() / xyz[i].z() + intr->cy;
                if (std::abs(u - 0.5 * intr->width) > intr->width / 6.0 ||
                    std::abs(w - 0.5 * intr->height) > intr->height / 6.0)
                    continue;
            }
            footprint.push_back(xyz[i].z() / f);
        }
    }
    if (footprint.empty()) return 0.005;
    return std::max(0.005, 3.0 * rank_quantile(footprint, 0.5));
}

/// How many views hold world point p in their viewing frustum (image bounds, depth up to the
/// view's far limit).
int frustum_count(const Eigen::Vector3d& p, const std::vector<PointCloud>& views,
                  const std::vector<double>& far_m) {
    int count = 0;
    for (std::size_t v = 0; v < views.size(); ++v) {
        const auto& intr = views[v].view.intrinsics;
        const Eigen::Vector3d q = views[v].view.world_from_sensor->inverse() * p;
        if (q.z() <= 0 || q.z() > far_m[v]) continue;
        if (!intr) {
            ++count;
            continue;
        }
        const double u = intr->fx * q.x() / q.z() + intr->cx;
        const double w = intr->fy * q.y() / q.z() + intr->cy;
        count += u > -0.5 && w > -0.5 && u < intr->width - 0.5 && w < intr->height - 0.5;
    }
    return count;
}

/// The subject is what the sensors aim at: each view votes for the regions (`region` per voxel,
/// -1 none) of its points (`point_voxel` per point), weighted by a Gaussian around its principal
/// point (sigma a sixth of the image's larger side); a sensor looking elsewhere casts one vote
/// among many. Returns the summed votes per region (each view's votes sum to 1).
std::unordered_map<int, double> aim_votes(const std::vector<ViewPoints>& vps,
                                          const std::vector<PointCloud>& views,
                                          const std::vector<std::vector<int>>& point_voxel,
                                          const std::vector<int>& region) {
    std::unordered_map<int, double> votes;
    for (std::size_t v = 0; v < vps.size(); ++v) {
        const auto& intr = views[v].view.intrinsics;
        std::unordered_map<int, double> view_votes;
        double total = 0;
        for (std::size_t i = 0; i < vps[v].g.xyz.size(); ++i) {
            const int c = point_voxel[v][i];
            if (c < 0 || region[c] < 0) continue;
            double w = 1.0;
            if (intr) {
                const Eigen::Vector3d& q = vps[v].g.xyz[i];
                const double sigma = std::max(intr->width, intr->height) / 6.0;
                const double du = intr->fx * q.x() / q.z() + intr->cx - 0.5 * (intr->width - 1);
                const double dv = intr->fy * q.y() / q.z() + intr->cy - 0.5 * (intr->height - 1);
                w = std::exp(-(du * du + dv * dv) / (2 * sigma * sigma));
            }
            view_votes[region[c]] += w;
            total += w;
        }
        if (total > 0)
            for (const auto& [r, w] : view_votes) votes[r] += w / total;
    }
    return votes;
}

/// Steps 2 and 3: regions of the points not yet removed, the subject among them; marks every
/// other point removed. Adds voxel_m, core_views, regions, subject_regions to the report.
void select_subject(std::vector<ViewPoints>& vps, const std::vector<PointCloud>& views,
                    const SubjectOptions& o, Report& report) {
    const double voxel = o.voxel_m > 0 ? o.voxel_m : auto_voxel(vps, views);
    report["voxel_m"] = voxel;
    // Voxels of the live points.
    std::unordered_map<std::int64_t, int> index;
    std::vector<Eigen::Vector3i> cells;
    std::vector<int> counts;
    std::vector<std::vector<int>> point_voxel(vps.size());
    for (std::size_t v = 0; v < vps.size(); ++v) {
        point_voxel[v].assign(vps[v].world.size(), -1);
        for (std::size_t i = 0; i < vps[v].world.size(); ++i) {
            if (vps[v].removed[i]) continue;
            const Eigen::Vector3i c = (vps[v].world[i] / voxel).array().floor().cast<int>();
            const auto [it, inserted] =
                index.try_emplace(voxel_key(c), static_cast<int>(cells.size()));
            if (inserted) cells.push_back(c), counts.push_back(0);
            ++counts[it->second];
            point_voxel[v][i] = it->second;
        }
    }
    const int nv = static_cast<int>(cells.size());
    RGBD_CHECK(nv > 0, "nothing above the ground");
    // Solid voxels linked by 26-adjacency.
    Components uf;
    uf.parent.resize(nv);
    for (int i = 0; i < nv; ++i) uf.parent[i] = i;
    auto neighbour = [&](int i, int dx, int dy, int dz) {
        const auto it = index.find(voxel_key(cells[i] + Eigen::Vector3i(dx, dy, dz)));
        return it == index.end() ? -1 : it->second;
    };
    for (int i = 0; i < nv; ++i) {
        if (counts[i] < o.solid_points) continue;
        for (int dx = -1; dx <= 1; ++dx)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dz = -1; dz <= 1; ++dz) {
                    const int j = neighbour(i, dx, dy, dz);
                    if (j > i && counts[j] >= o.solid_points) uf.unite(i, j);
                }
    }
    // Thin voxels join a solid neighbour's region; -1: none (dropped).
    std::vector<int> region(nv, -1);
    for (int i = 0; i < nv; ++i) {
        if (counts[i] >= o.solid_points) {
            region[i] = uf.find(i);
            continue;
        }
        for (int dx = -1; dx <= 1 && region[i] < 0; ++dx)
            for (int dy = -1; dy <= 1 && region[i] < 0; ++dy)
                for (int dz = -1; dz <= 1 && region[i] < 0; ++dz) {
                    const int j = neighbour(i, dx, dy, dz);
                    if (j >= 0 && counts[j] >= o.solid_points) region[i] = uf.find(j);
                }
    }
    // The co-visible core, per voxel.
    std::vector<double> far_m(views.size(), 0);
    for (std::size_t v = 0; v < views.size(); ++v) {
        std::vector<double> z;
        for (const auto& q : vps[v].g.xyz) z.push_back(q.z());
        far_m[v] = z.empty() ? 0 : 1.05 * rank_quantile(z, 0.99);
    }
    const int n_views = static_cast<int>(views.size());
    const int core_views =
        n_views == 1 ? 1 : std::max(2, static_cast<int>(std::ceil(o.core_share * n_views - 1e-9)));
    report["core_views"] = core_views;
    std::vector<std::uint8_t> in_core(nv, 0);
    tbb::parallel_for(0, nv, [&](int i) {
        if (region[i] < 0) return;
        const Eigen::Vector3d centre = (cells[i].cast<double>().array() + 0.5).matrix() * voxel;
        in_core[i] = frustum_count(centre, views, far_m) >= core_views;
    });
    // Per region: points, points in the core.
    std::unordered_map<int, std::pair<std::size_t, std::size_t>> sizes;
    for (int i = 0; i < nv; ++i) {
        if (region[i] < 0) continue;
        auto& s = sizes[region[i]];
        s.first += counts[i];
        if (in_core[i]) s.second += counts[i];
    }
    report["regions"] = sizes.size();
    RGBD_CHECK(!sizes.empty(), "nothing above the ground forms a connected region");
    const std::unordered_map<int, double> votes = aim_votes(vps, views, point_voxel, region);
    int subject = -1;
    double best = 0;
    for (const auto& [r, vote] : votes)
        if (vote > best || (vote == best && subject >= 0 && r < subject)) best = vote, subject = r;
    RGBD_CHECK(subject >= 0 && sizes[subject].second > 0,
               "no region above the ground lies where the sensors look together");
    report["subject_votes"] = best;
    // Join regions mostly in the core within the gap of the subject (coarse cells of the gap).
    std::unordered_map<int, char> keep{{subject, 1}};
    const double gap = std::max(o.join_gap_m, voxel);
    std::unordered_map<std::int64_t, char> subject_cells;
    for (int i = 0; i < nv; ++i)
        if (region[i] == subject)
            subject_cells[voxel_key(
                ((cells[i].cast<double>().array() + 0.5) * voxel / gap).floor().cast<int>())] = 1;
    for (int i = 0; i < nv; ++i) {
        const int r = region[i];
        if (r < 0 || keep.count(r)) continue;
        const auto& s = sizes[r];
        if (s.second < o.join_core_share * s.first) continue;
        const Eigen::Vector3i g =
            ((cells[i].cast<double>().array() + 0.5) * voxel / gap).floor().cast<int>();
        bool near = false;
        for (int dx = -1; dx <= 1 && !near; ++dx)
            for (int dy = -1; dy <= 1 && !near; ++dy)
                for (int dz = -1; dz <= 1 && !near; ++dz)
                    near = subject_cells.count(voxel_key(g + Eigen::Vector3i(dx, dy, dz))) > 0;
        if (near) keep[r] = 1;
    }
    report["subject_regions"] = keep.size();
    std::size_t subject_points = 0;
    for (const auto& [r, flag] : keep) subject_points += sizes[r].first;
    // Noise left above the ground (far floor beyond the margin, stray returns) is not a
    // subject: a subject gives each view dozens of points at least.
    RGBD_CHECK(subject_points >= 50 * vps.size(),
               "nothing above the ground forms a subject (the largest region the sensors aim at "
               "has " +
                   std::to_string(subject_points) + " points in " + std::to_string(vps.size()) +
                   " views)");
    // A subject mostly outside the co-visible core is touching something large (a wall, a
    // table): say so rather than keep it silently.
    std::size_t points = 0, core = 0;
    for (const auto& [r, flag] : keep) points += sizes[r].first, core += sizes[r].second;
    report["subject_core_share"] = points ? static_cast<double>(core) / points : 0.0;
    if (points && core < 0.6 * points)
        report["note"] =
            "extraction: only " + std::to_string(static_cast<int>(100.0 * core / points)) +
            "% of the subject lies where the sensors look together: it may touch a wall or "
            "other large structure, which is kept with it (--crop-radius-m limits the extent)";
    for (std::size_t v = 0; v < vps.size(); ++v)
        for (std::size_t i = 0; i < vps[v].world.size(); ++i) {
            const int c = point_voxel[v][i];
            if (c >= 0 && (region[c] < 0 || !keep.count(region[c]))) vps[v].removed[i] = 1;
        }
}

}  // namespace

void SubjectOptions::check() const {
    check_range("extraction: ground max tilt", ground_max_tilt_deg, Range::open(0, 90), "deg");
    check_range("extraction: ground band", ground_band_m, Range::open(0, 1), "m");
    check_range("extraction: ground min share", ground_min_share, Range::open(0, 1));
    check_range("extraction: ground sigmas", ground_sigmas, Range::closed_open(0, 100));
    check_range("extraction: wall max behind share", wall_max_behind_share, Range::closed(0, 1));
    check_range("extraction: wall max through share", wall_max_through_share, Range::closed(0, 1));
    check_range("extraction: wall split tilt", wall_split_tilt_deg, Range::open_closed(0, 90),
                "deg");
    check_range("extraction: ground flat sigmas", ground_flat_sigmas, Range::open(0, 100));
    check_range("extraction: ground min margin", ground_min_margin_m, Range::closed_open(0, 1),
                "m");
    check_range("extraction: voxel", voxel_m, Range::closed_open(0, 1), "m");
    check_range("extraction: core share", core_share, Range::closed(0, 1));
    check_range("extraction: join gap", join_gap_m, Range::closed_open(0, 10), "m");
    check_range("extraction: join core share", join_core_share, Range::closed(0, 1));
    RGBD_CHECK(solid_points >= 1 && iterations >= 1 && max_samples >= 100,
               "extraction: solid points >= 1, iterations >= 1, samples >= 100");
}

std::optional<ViewGround> view_ground(const PointCloud& view) {
    for (const auto& c : view.view.extra_comments) {
        if (c.rfind(kGroundKey, 0) != 0) continue;
        std::istringstream s(c.substr(std::string(kGroundKey).size()));
        ViewGround g;
        s >> g.normal.x() >> g.normal.y() >> g.normal.z() >> g.offset >> g.margin_m;
        RGBD_CHECK(s && g.normal.allFinite() && std::abs(g.normal.norm() - 1) < 1e-3 &&
                       std::isfinite(g.offset) && std::isfinite(g.margin_m) && g.margin_m >= 0,
                   "view " + std::to_string(view.view.id) + ": malformed '" + c +
                       "' (expected a unit normal, an offset and a margin in metres)");
        return g;
    }
    return std::nullopt;
}

std::optional<ViewGround> world_ground(const std::vector<PointCloud>& views) {
    Eigen::Vector3d n = Eigen::Vector3d::Zero();
    double d = 0, margin = 0;
    int count = 0;
    for (const auto& v : views) {
        const auto g = view_ground(v);
        if (!g || !v.view.world_from_sensor) continue;
        // The plane in the world: n_w = R n, d_w = d - n_w . t.
        const Pose& pose = *v.view.world_from_sensor;
        const Eigen::Vector3d nw = pose.linear() * g->normal;
        n += nw;
        d += g->offset - nw.dot(pose.translation());
        margin = std::max(margin, g->margin_m);
        ++count;
    }
    if (count == 0 || n.norm() < 1e-9) return std::nullopt;
    ViewGround w;
    const double len = n.norm();
    w.normal = n / len;
    w.offset = d / count / (len / count);
    w.margin_m = margin;
    return w;
}

Report extract_subject(std::vector<PointCloud>& views,
                       const std::vector<denoise::NoiseModel>& noise, const SubjectOptions& options,
                       bool mark, const Progress& progress,
                       std::vector<Eigen::Vector3d>* removed_world) {
    options.check();
    const Stopwatch watch;
    Report report = {{"removed", 0}};
    RGBD_CHECK(noise.size() == 1 || noise.size() == views.size(),
               "extraction: one noise model, or one per view");
    for (const auto& v : views)
        if (v.view.frame != ViewFrame::kSensor || !v.view.world_from_sensor) {
            report["note"] = "extraction: a view has no sensor pose; nothing removed";
            report["time_s"] = watch.seconds();
            return report;
        }
    std::vector<ViewPoints> vps(views.size());
    tbb::parallel_for(std::size_t{0}, views.size(), [&](std::size_t v) {
        vps[v].g = denoise::detail::gather(views[v]);
        const Pose& pose = *views[v].view.world_from_sensor;
        vps[v].world.reserve(vps[v].g.xyz.size());
        for (const auto& p : vps[v].g.xyz) vps[v].world.push_back(pose * p);
        vps[v].removed.assign(vps[v].g.xyz.size(), 0);
        const auto pixels = views[v].pixel_map();
        const auto& info = views[v].view;
        if (pixels && info.has_grid()) {
            vps[v].width = info.grid_width;
            vps[v].height = info.grid_height;
            vps[v].at.assign(static_cast<std::size_t>(info.grid_width) * info.grid_height, -1);
            for (std::size_t i = 0; i < vps[v].g.ids.size(); ++i) {
                const std::uint32_t px = (*pixels)[vps[v].g.ids[i]];
                vps[v].pixel.push_back(px);
                if (px < vps[v].at.size()) vps[v].at[px] = static_cast<int>(i);
            }
        }
    });
    std::size_t total = 0;
    for (const auto& vp : vps) total += vp.world.size();
    if (total == 0) {
        report["note"] = "extraction: no points";
        report["time_s"] = watch.seconds();
        return report;
    }

    // The override: a ball around the given centre.
    const bool crop = options.crop_radius_m > 0 && options.crop_centre;
    if (crop) {
        std::size_t n = 0;
        const double r2 = options.crop_radius_m * options.crop_radius_m;
        for (auto& vp : vps)
            for (std::size_t i = 0; i < vp.world.size(); ++i)
                if ((vp.world[i] - *options.crop_centre).squaredNorm() > r2) vp.removed[i] = 1, ++n;
        report["crop"] = {
            {"radius_m", options.crop_radius_m},
            {"centre_m",
             {options.crop_centre->x(), options.crop_centre->y(), options.crop_centre->z()}},
            {"removed", n}};
    }

    // 1. The ground.
    report["ground"] = detail::remove_ground(vps, views, noise, options, total);
    // The walls belong to the selection of the subject (ground only: the ground alone).
    if (options.remove_ground && options.select_subject && !crop)
        report["walls"] = detail::remove_walls(vps, views, noise, options,
                                               report["ground"].value("found", false)
                                                   ? report["ground"].value("flatness_sigmas", 1.0)
                                                   : 1.0);
    report_progress(progress, 0.4);
    std::size_t left = 0;
    for (const auto& vp : vps)
        for (auto r : vp.removed) left += !r;
    if (left == 0 && crop) {
        report["note"] = "extraction: the crop (--crop-radius-m) removed every point";
    } else if (left == 0)
        throw InputError("extraction: nothing above the ground (every point of the " +
                         std::to_string(views.size()) + " views lies on or below it)");

    // 2-3. Regions and the subject.
    if (options.select_subject && !crop && left > 0) select_subject(vps, views, options, report);
    report_progress(progress, 0.8);

    if (removed_world) {
        removed_world->clear();
        std::size_t n = 0;
        for (const auto& vp : vps)
            for (auto r : vp.removed) n += r;
        const std::size_t stride = std::max<std::size_t>(1, (n + 199999) / 200000);
        std::size_t k = 0;
        for (const auto& vp : vps)
            for (std::size_t i = 0; i < vp.world.size(); ++i)
                if (vp.removed[i] && k++ % stride == 0) removed_world->push_back(vp.world[i]);
    }

    // Apply.
    Report per_view = Report::array();
    std::size_t removed = 0, kept = 0;
    for (std::size_t v = 0; v < views.size(); ++v) {
        const std::size_t n = denoise::detail::apply(views[v], vps[v].g, vps[v].removed, mark);
        removed += n;
        kept += vps[v].removed.size() - n;
        per_view.push_back(
            {{"view", views[v].view.id}, {"removed", n}, {"kept", vps[v].removed.size() - n}});
    }
    if (kept == 0 && !crop) throw InputError("extraction: nothing of the subject is left");
    report["removed"] = removed;
    report["kept"] = kept;
    report["views"] = per_view;
    report_progress(progress, 1.0);
    report["time_s"] = watch.seconds();
    return report;
}

}  // namespace rgbd::segment
