#include "algorithms/sampling/voxel_downsample.hpp"

#include <tbb/parallel_for.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "algorithms/internal/voxel_grid.hpp"
#include "toolkit/error.hpp"

namespace rgbd::sampling {

namespace {
constexpr std::int64_t kMaxCells = std::int64_t{1} << internal::kVoxelKeyBits;

std::string view_name(const PointCloud& cloud) { return "view " + std::to_string(cloud.view.id); }
}  // namespace

PointCloud voxel_downsample(const PointCloud& cloud, double voxel_m) {
    RGBD_CHECK(std::isfinite(voxel_m) && voxel_m > 0.0, "voxel_downsample: " + view_name(cloud) +
                                                            ": voxel size must be positive, got " +
                                                            format_number(voxel_m));
    PointCloud out;
    out.view = cloud.view;
    out.view.grid_width = 0;
    out.view.grid_height = 0;
    out.points.copy_properties(cloud.points);
    if (cloud.empty()) return out;

    const PointSet& in = cloud.points;
    std::vector<PointSet::Index> index;
    std::vector<Eigen::Vector3d> xyz;
    index.reserve(in.size());
    xyz.reserve(in.size());
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Vector3d hi = -lo;
    for (auto idx : in) {
        const Eigen::Vector3d p = to_eigen(in.point(idx));
        RGBD_CHECK(p.allFinite(), "voxel_downsample: " + view_name(cloud) + ": point " +
                                      std::to_string(xyz.size()) + " is not finite");
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
        index.push_back(idx);
        xyz.push_back(p);
    }
    const Eigen::Vector3d extent = (hi - lo) / voxel_m;
    RGBD_CHECK(extent.maxCoeff() < static_cast<double>(kMaxCells - 1),
               "voxel_downsample: " + view_name(cloud) + ": voxel " + format_number(voxel_m) +
                   " m is too small for the extent of the cloud");

    // (voxel key, point position in xyz) pairs, a voxel's points consecutive.
    internal::VoxelKeyed keyed;
    internal::sort_by_voxel(xyz, lo, voxel_m, keyed);
    const std::vector<std::size_t> starts = internal::voxel_starts(keyed);  // group boundaries
    const std::size_t groups = starts.size() - 1;

    const bool has_normals = in.has_normal_map();
    const bool has_colors = cloud.has_colors();
    std::optional<PointCloud::ColorMaps> in_colors;
    if (has_colors) in_colors = cloud.colors();

    struct Cell {
        Eigen::Vector3d centroid;
        Eigen::Vector3d normal;
        Rgb color;
        std::uint32_t representative;
    };
    std::vector<Cell> cells(groups);
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, groups, 256),
        [&](const tbb::blocked_range<std::size_t>& r) {
            for (std::size_t g = r.begin(); g != r.end(); ++g) {
                Cell& cell = cells[g];
                const std::size_t b = starts[g], e = starts[g + 1];
                const double count = static_cast<double>(e - b);
                Eigen::Vector3d sum = Eigen::Vector3d::Zero();
                Eigen::Vector3d nsum = Eigen::Vector3d::Zero();
                double rsum = 0, gsum = 0, bsum = 0;
                for (std::size_t k = b; k < e; ++k) {
                    const std::uint32_t i = keyed[k].second;
                    sum += xyz[i];
                    if (has_normals) nsum += to_eigen(in.normal(index[i]));
                    if (has_colors) {
                        const Rgb c = in_colors->get(index[i]);
                        rsum += c.r;
                        gsum += c.g;
                        bsum += c.b;
                    }
                }
                cell.centroid = sum / count;
                cell.representative = internal::nearest_in_voxel(keyed, b, e, xyz, cell.centroid);
                if (has_normals) {
                    const double len = nsum.norm();
                    cell.normal = len > 1e-12 ? Eigen::Vector3d(nsum / len)
                                              : to_eigen(in.normal(index[cell.representative]));
                }
                if (has_colors) {
                    auto avg = [count](double s) {
                        return static_cast<std::uint8_t>(std::lround(s / count));
                    };
                    cell.color = {avg(rsum), avg(gsum), avg(bsum)};
                }
            }
        });

    out.points.reserve(groups);
    for (const Cell& cell : cells) out.points.insert(in, index[cell.representative]);
    std::optional<PointCloud::ColorMaps> out_colors;
    if (has_colors) out_colors = out.colors();
    std::size_t g = 0;
    for (auto idx : out.points) {
        const Cell& cell = cells[g++];
        out.points.point(idx) = to_point(cell.centroid);
        if (has_normals) out.points.normal(idx) = to_vector(cell.normal);
        if (has_colors) out_colors->set(idx, cell.color);
    }
    return out;
}

}  // namespace rgbd::sampling
