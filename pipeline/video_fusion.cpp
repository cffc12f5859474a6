#include "pipeline/video_fusion.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

#include "algorithms/frames/object_extraction.hpp"
#include "algorithms/sampling/merge_views.hpp"
#include "algorithms/sampling/voxel_downsample.hpp"
#include "toolkit/error.hpp"
#include "toolkit/srgb.hpp"

namespace rgbd::pipeline {

void VideoFusionOptions::check() const {
    cloud.check();
    distance.check();
    check_range("video fusion: voxel", voxel_m, Range::closed(0, 0.5), "m (0 = from the rig)");
    check_range("video fusion: duplicate radius", duplicate_radius_voxels, Range::closed(0, 10),
                "voxels");
    RGBD_CHECK(std::isfinite(max_delta_e) && max_delta_e >= 0,
               "video fusion: max Delta E must be >= 0");
    RGBD_CHECK(std::isfinite(extraction.crop_radius_m) && extraction.crop_radius_m >= 0,
               "video fusion: crop radius must be >= 0");
}

double video_voxel_m(const io::Rig& rig, const std::optional<Eigen::Vector3d>& centre) {
    std::vector<double> footprints;
    for (const io::SensorSpec& s : rig.sensors) {
        const double f = 0.5 * (s.depth.fx + s.depth.fy);
        if (!(f > 0)) continue;
        double z = 1.5;
        if (centre && s.has_world_from_depth) z = (s.world_from_depth.inverse() * *centre).z();
        if (!(z > 0)) z = 1.5;
        footprints.push_back(z / f);
    }
    if (footprints.empty()) return 0.004;
    std::nth_element(footprints.begin(), footprints.begin() + footprints.size() / 2,
                     footprints.end());
    return footprints[footprints.size() / 2];
}

PointCloud fusion_view(const RgbdFrame& frame, int view_id, const VideoFusionOptions& options,
                       const std::optional<Eigen::Vector3d>& centre, Report* report) {
    const Stopwatch watch;
    Report r;
    PointCloud view = frames::depth_to_cloud(frame, options.cloud, nullptr);
    view.view.id = view_id;
    view.view.frame_index = frame.frame_index;
    r["points_in_window"] = view.size();
    if (centre && options.extraction.crop_radius_m > 0)
        frames::crop_to_sphere(view, *centre, options.extraction.crop_radius_m);
    r["points_cropped"] = view.size();
    const double cloud_ms = 1e3 * watch.seconds();
    if (options.clean && view.size() > 0) {
        const Report clean = denoise::remove_distance_outliers(view, options.distance);
        r["removed"] = clean.value("removed", 0);
    }
    r["points"] = view.size();
    if (!view.view.world_from_sensor) {
        view.view.world_from_sensor = frame.world_from_sensor;
    }
    to_world_frame(view);
    r["cloud_ms"] = cloud_ms;
    r["ms"] = 1e3 * watch.seconds();
    if (report) *report = std::move(r);
    return view;
}

namespace {

/// CIE L*a*b* (D65) of a mean sRGB colour given as sums over `n` points.
Eigen::Vector3f lab_of(const Eigen::Vector3f& rgb_mean) {
    const auto& lin = srgb_linear_table();
    const auto channel = [&](float v) {
        const int i = std::clamp(static_cast<int>(std::lround(v)), 0, 255);
        return lin[i];
    };
    const float r = channel(rgb_mean.x()), g = channel(rgb_mean.y()), b = channel(rgb_mean.z());
    const float x = (0.4124f * r + 0.3576f * g + 0.1805f * b) / 0.95047f;
    const float y = 0.2126f * r + 0.7152f * g + 0.0722f * b;
    const float z = (0.0193f * r + 0.1192f * g + 0.9505f * b) / 1.08883f;
    const auto f = [](float t) {
        return t > 216.0f / 24389.0f ? std::cbrt(t) : (24389.0f / 27.0f * t + 16.0f) / 116.0f;
    };
    const float fx = f(x), fy = f(y), fz = f(z);
    return {116.0f * fy - 16.0f, 500.0f * (fx - fy), 200.0f * (fy - fz)};
}

}  // namespace

io::ColoredPoints fuse_points(const std::vector<FusionView>& views, double voxel_m,
                              const VideoFusionOptions& options, Report* report) {
    RGBD_CHECK(std::isfinite(voxel_m) && voxel_m > 0, "video fusion: voxel must be > 0");
    const Stopwatch watch;
    std::size_t total = 0;
    Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
    Eigen::Vector3f hi = -lo;
    int present = 0;
    for (const FusionView& v : views) {
        if (!v.points || v.points->size() == 0) continue;
        RGBD_CHECK(v.points->rgb.empty() || v.points->rgb.size() == v.points->size(),
                   "video fusion: colour count differs from point count");
        ++present;
        total += v.points->size();
        for (const Eigen::Vector3f& p : v.points->xyz) {
            RGBD_CHECK(p.allFinite(), "video fusion: non-finite point");
            lo = lo.cwiseMin(p);
            hi = hi.cwiseMax(p);
        }
    }
    io::ColoredPoints out;
    if (total == 0) {
        if (report) *report = Report{{"views", 0}, {"input_points", 0}, {"points", 0}};
        return out;
    }
    const double inv = 1.0 / voxel_m;
    constexpr std::int64_t kAxis = std::int64_t{1} << 21;
    RGBD_CHECK((hi - lo).maxCoeff() * inv < static_cast<double>(kAxis - 1),
               "video fusion: more than 2^21 voxels along an axis (voxel too small)");
    // (voxel key, view, index in the view): sorted, a voxel's points are contiguous and, in
    // it, grouped by view.
    struct Entry {
        std::uint64_t key;
        std::uint32_t view, index;
        bool operator<(const Entry& o) const {
            return key != o.key ? key < o.key : view != o.view ? view < o.view : index < o.index;
        }
    };
    std::vector<Entry> entries;
    entries.reserve(total);
    for (std::size_t v = 0; v < views.size(); ++v) {
        if (!views[v].points) continue;
        const auto& xyz = views[v].points->xyz;
        for (std::size_t i = 0; i < xyz.size(); ++i) {
            const Eigen::Vector3f d = (xyz[i] - lo) * static_cast<float>(inv);
            const auto ix = static_cast<std::uint64_t>(d.x()),
                       iy = static_cast<std::uint64_t>(d.y()),
                       iz = static_cast<std::uint64_t>(d.z());
            entries.push_back({(ix << 42) | (iy << 21) | iz, static_cast<std::uint32_t>(v),
                               static_cast<std::uint32_t>(i)});
        }
    }
    std::sort(entries.begin(), entries.end());

    // 1. Cells: one view's points in one voxel (centroid, mean colour, mean squared distance to
    //    the sensor), in key order and, within a voxel, view order.
    struct Cell {
        std::uint64_t key;
        std::uint32_t view;
        bool alive = true;
        int count = 0;
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        Eigen::Vector3f rgb = Eigen::Vector3f::Zero();
        bool colour = false;
        double dist2 = 0;
        Eigen::Vector3f lab = Eigen::Vector3f::Zero();
        Eigen::Vector3d centroid() const { return sum / count; }
    };
    std::vector<Cell> cells;
    cells.reserve(total / 2);
    for (const Entry& e : entries) {
        if (cells.empty() || cells.back().key != e.key || cells.back().view != e.view)
            cells.push_back(Cell{e.key, e.view});
        Cell& c = cells.back();
        const FusionView& v = views[e.view];
        const Eigen::Vector3d p = v.points->xyz[e.index].cast<double>();
        c.sum += p;
        c.dist2 += (p - v.sensor).squaredNorm();
        if (!v.points->rgb.empty()) {
            const Rgb col = v.points->rgb[e.index];
            c.rgb += Eigen::Vector3f(col.r, col.g, col.b);
            c.colour = true;
        }
        ++c.count;
    }
    for (Cell& c : cells) {
        c.dist2 /= c.count;
        if (c.colour) c.lab = lab_of(c.rgb / static_cast<float>(c.count));
    }
    // 2. Column (ix, iy) -> its first cell (cells are sorted by key, so a column's cells are
    //    contiguous and ordered by iz): open addressing, power-of-two table.
    const auto column_of = [](std::uint64_t key) { return key >> 21; };
    std::size_t table_size = 16;
    int table_bits = 4;
    while (table_size < 2 * cells.size()) {
        table_size *= 2;
        ++table_bits;
    }
    std::vector<std::uint64_t> table_key(table_size, 0);  // column + 1; 0 = empty
    std::vector<std::uint32_t> table_cell(table_size, 0);
    const auto slot_of = [&](std::uint64_t column) {
        return static_cast<std::size_t>((column * 0x9E3779B97F4A7C15ULL) >> (64 - table_bits));
    };
    for (std::size_t i = 0; i < cells.size(); ++i) {
        if (i > 0 && column_of(cells[i - 1].key) == column_of(cells[i].key)) continue;
        std::size_t slot = slot_of(column_of(cells[i].key));
        while (table_key[slot] != 0) slot = (slot + 1) & (table_size - 1);
        table_key[slot] = column_of(cells[i].key) + 1;
        table_cell[slot] = static_cast<std::uint32_t>(i);
    }
    const auto first_cell = [&](std::uint64_t column) -> std::int64_t {
        for (std::size_t slot = slot_of(column);; slot = (slot + 1) & (table_size - 1)) {
            if (table_key[slot] == 0) return -1;
            if (table_key[slot] == column + 1) return table_cell[slot];
        }
    };
    // 3. Duplicate removal between views, view by view in rig order (docs/algorithms.md §6.2
    //    step 6 on cells instead of points): a cell with an earlier view's live cell within
    //    duplicate_radius_voxels voxels (3 x 3 x 3 neighbourhood) of the same colour is a
    //    duplicate; if the colours differ, the better observed (nearer its sensor) stays.
    std::vector<std::vector<std::uint32_t>> by_view(views.size());
    for (std::size_t i = 0; i < cells.size(); ++i) by_view[cells[i].view].push_back(i);
    const double radius2 = std::pow(options.duplicate_radius_voxels * voxel_m, 2);
    const double max_de2 = options.max_delta_e * options.max_delta_e;
    std::size_t duplicates = 0, replaced = 0;
    std::vector<std::uint32_t> conflicting;
    if (radius2 > 0) {
        for (std::size_t v = 0; v < views.size(); ++v) {
            for (const std::uint32_t i : by_view[v]) {
                Cell& c = cells[i];
                const std::int64_t ix = static_cast<std::int64_t>(c.key >> 42),
                                   iy = static_cast<std::int64_t>((c.key >> 21) & (kAxis - 1)),
                                   iz = static_cast<std::int64_t>(c.key & (kAxis - 1));
                const Eigen::Vector3d p = c.centroid();
                bool same = false, best = true;
                conflicting.clear();
                for (int dx = -1; dx <= 1 && !same; ++dx)
                    for (int dy = -1; dy <= 1 && !same; ++dy) {
                        const std::int64_t x = ix + dx, y = iy + dy;
                        if (x < 0 || y < 0) continue;
                        const std::uint64_t column =
                            (static_cast<std::uint64_t>(x) << 21) | static_cast<std::uint64_t>(y);
                        std::int64_t j = first_cell(column);
                        if (j < 0) continue;
                        for (; static_cast<std::size_t>(j) < cells.size(); ++j) {
                            const Cell& o = cells[static_cast<std::size_t>(j)];
                            if (column_of(o.key) != column) break;
                            const auto z = static_cast<std::int64_t>(o.key & (kAxis - 1));
                            if (z < iz - 1) continue;
                            if (z > iz + 1) break;
                            if (o.view >= v || !o.alive) continue;
                            if ((o.centroid() - p).squaredNorm() > radius2) continue;
                            if (!c.colour || !o.colour ||
                                (o.lab - c.lab).squaredNorm() <= max_de2) {
                                same = true;
                                break;
                            }
                            best = best && c.dist2 < o.dist2;
                            conflicting.push_back(static_cast<std::uint32_t>(j));
                        }
                    }
                if (same) {
                    c.alive = false;
                    ++duplicates;
                } else if (!conflicting.empty()) {
                    if (best) {
                        for (const std::uint32_t j : conflicting) cells[j].alive = false;
                        replaced += conflicting.size();
                    } else {
                        c.alive = false;
                        ++replaced;
                    }
                }
            }
        }
    }
    // 4. One point per voxel: centroid and mean colour of its live cells.
    bool any_colour = false;
    for (const FusionView& v : views)
        any_colour = any_colour || (v.points && !v.points->rgb.empty());
    out.xyz.reserve(cells.size());
    if (any_colour) out.rgb.reserve(cells.size());
    for (std::size_t a = 0; a < cells.size();) {
        std::size_t b = a;
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        Eigen::Vector3f rgb = Eigen::Vector3f::Zero();
        int count = 0, coloured = 0;
        for (; b < cells.size() && cells[b].key == cells[a].key; ++b) {
            const Cell& c = cells[b];
            if (!c.alive) continue;
            sum += c.sum;
            count += c.count;
            if (c.colour) {
                rgb += c.rgb;
                coloured += c.count;
            }
        }
        a = b;
        if (count == 0) continue;
        out.xyz.push_back((sum / count).cast<float>());
        if (any_colour) {
            const Eigen::Vector3f m = coloured > 0
                                          ? Eigen::Vector3f(rgb / static_cast<float>(coloured))
                                          : Eigen::Vector3f(128, 128, 128);
            out.rgb.push_back(Rgb{static_cast<std::uint8_t>(std::lround(m.x())),
                                  static_cast<std::uint8_t>(std::lround(m.y())),
                                  static_cast<std::uint8_t>(std::lround(m.z()))});
        }
    }
    if (report)
        *report = Report{{"views", present},     {"input_points", total},
                         {"points", out.size()}, {"duplicates", duplicates},
                         {"replaced", replaced}, {"ms", 1e3 * watch.seconds()}};
    return out;
}

PointCloud fuse_views(std::vector<PointCloud>&& views, double voxel_m,
                      const VideoFusionOptions& options, Report* report) {
    RGBD_CHECK(std::isfinite(voxel_m) && voxel_m > 0, "video fusion: voxel must be > 0");
    const Stopwatch watch;
    Report r;
    std::vector<PointCloud> present;
    std::size_t input = 0;
    for (PointCloud& v : views) {
        if (v.empty()) continue;
        RGBD_CHECK(v.view.frame == ViewFrame::kWorld,
                   "video fusion: view " + std::to_string(v.view.id) + " is in its sensor frame");
        input += v.size();
        present.push_back(std::move(v));
    }
    r["views"] = present.size();
    r["input_points"] = input;
    if (present.empty()) {
        if (report) *report = std::move(r);
        PointCloud none;
        none.view.frame = ViewFrame::kWorld;
        return none;
    }
    PointCloud merged;
    if (options.duplicate_radius_voxels > 0 && present.size() > 1) {
        registration::DuplicateOptions dup;
        dup.spacing_m = voxel_m;
        dup.radius_spacing = options.duplicate_radius_voxels;
        dup.max_delta_e = options.max_delta_e;
        dup.noise_model = options.distance.noise_model;
        registration::DuplicateReport dr;
        merged = registration::merge_without_duplicates(std::move(present), dup, &dr);
        r["duplicates"] = dr.duplicates;
        r["replaced"] = dr.replaced;
    } else {
        merged = present.size() == 1 ? std::move(present.front())
                                     : sampling::merge_views(std::move(present));
    }
    r["merge_ms"] = 1e3 * watch.seconds();
    PointCloud fused = sampling::voxel_downsample(merged, voxel_m);
    fused.view.frame = ViewFrame::kWorld;
    fused.view.world_from_sensor.reset();
    r["points"] = fused.size();
    r["ms"] = 1e3 * watch.seconds();
    if (report) *report = std::move(r);
    return fused;
}

}  // namespace rgbd::pipeline
