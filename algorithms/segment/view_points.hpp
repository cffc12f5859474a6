// One view's points as the object extraction works on them (algorithms/segment/
// subject_extraction.hpp): sensor frame, world frame, the removal marks and the pixel grid.
// Internal to algorithms/segment.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <vector>

#include "algorithms/denoise/outlier_common.hpp"
#include "toolkit/pose.hpp"

namespace rgbd::segment::detail {

/// One view's live points in its sensor frame and in the world frame.
struct ViewPoints {
    denoise::detail::Gathered g;         ///< sensor-frame points and their indices
    std::vector<Eigen::Vector3d> world;  ///< the same points in the world frame
    std::vector<std::uint8_t> removed;   ///< per point: 1 = not the subject
    std::vector<int> at;                 ///< pixel -> position in g (-1: none); empty: no grid
    int width = 0, height = 0;
    std::vector<std::uint32_t> pixel;      ///< per point: its pixel
    std::vector<Eigen::Vector3d> normals;  ///< sensor-frame grid normals (sensor_normals)

    /// The grid normals of all points in the sensor frame, computed once; empty without a grid.
    const std::vector<Eigen::Vector3d>& sensor_normals() {
        if (normals.empty() && !at.empty()) {
            normals.resize(g.xyz.size());
            for (std::size_t i = 0; i < normals.size(); ++i)
                normals[i] = grid_normal(i, Pose::Identity());
        }
        return normals;
    }

    /// The unit normal of point i in the world frame from its pixel neighbours (central
    /// differences, depth-continuous within 5%), oriented towards the sensor; zero when the
    /// view has no grid or a neighbour is missing (the ground test then takes the point as
    /// possibly facing up).
    Eigen::Vector3d grid_normal(std::size_t i, const Pose& world_from_sensor) const {
        if (at.empty()) return Eigen::Vector3d::Zero();
        const int u = static_cast<int>(pixel[i] % width), r = static_cast<int>(pixel[i] / width);
        const Eigen::Vector3d& p = g.xyz[i];
        // The nearest valid pixel within 3 steps in each direction (registered depth maps
        // have regular holes).
        auto neighbour = [&](int du, int dr, Eigen::Vector3d& q) {
            for (int k = 1; k <= 3; ++k) {
                const int uu = u + k * du, rr = r + k * dr;
                if (uu < 0 || rr < 0 || uu >= width || rr >= height) return false;
                const int j = at[static_cast<std::size_t>(rr) * width + uu];
                if (j < 0) continue;
                q = g.xyz[j];
                return std::abs(q.z() - p.z()) < 0.05 * k * p.z();
            }
            return false;
        };
        Eigen::Vector3d a, b, c, d;
        if (!neighbour(1, 0, a) || !neighbour(-1, 0, b) || !neighbour(0, 1, c) ||
            !neighbour(0, -1, d))
            return Eigen::Vector3d::Zero();
        Eigen::Vector3d n = (a - b).cross(c - d);
        if (n.norm() < 1e-12) return Eigen::Vector3d::Zero();
        n.normalize();
        if (n.dot(p) > 0) n = -n;  // towards the sensor at the origin
        return world_from_sensor.linear() * n;
    }
};

}  // namespace rgbd::segment::detail
