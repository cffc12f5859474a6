#include "algorithms/frames/object_extraction.hpp"

#include <Eigen/Dense>
#include <cmath>

#include "toolkit/error.hpp"

namespace rgbd::frames {

std::optional<Eigen::Vector3d> axes_convergence_point(const std::vector<Pose>& poses) {
    if (poses.size() < 2) return std::nullopt;
    // Minimise sum_i |(I - d_i d_i^T)(x - c_i)|^2: A x = b with A = sum (I - d d^T).
    Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    for (const Pose& pose : poses) {
        const Eigen::Vector3d d = pose.linear().col(2).normalized();
        const Eigen::Matrix3d p = Eigen::Matrix3d::Identity() - d * d.transpose();
        a += p;
        b += p * pose.translation();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(a);
    // Parallel axes leave one direction unconstrained: the smallest eigenvalue vanishes.
    if (eig.eigenvalues()(0) < 1e-3 * static_cast<double>(poses.size())) return std::nullopt;
    const Eigen::Vector3d x = a.ldlt().solve(b);
    for (const Pose& pose : poses)
        if ((x - pose.translation()).dot(pose.linear().col(2)) <= 0) return std::nullopt;
    return x;
}

Report crop_to_sphere(PointCloud& cloud, const Eigen::Vector3d& centre_world, double radius_m,
                      bool mark) {
    RGBD_CHECK(std::isfinite(radius_m) && radius_m > 0, "crop radius must be positive");
    Pose world_from_points = Pose::Identity();
    if (cloud.view.frame == ViewFrame::kSensor) {
        RGBD_CHECK(cloud.view.world_from_sensor.has_value(),
                   "view " + std::to_string(cloud.view.id) +
                       " has no world_from_sensor pose to crop in the world frame");
        world_from_points = *cloud.view.world_from_sensor;
    }
    const double r2 = radius_m * radius_m;
    auto outside = [&](PointSet::Index i) {
        return (world_from_points * to_eigen(cloud.points.point(i)) - centre_world).squaredNorm() >
               r2;
    };
    std::size_t removed = 0;
    if (mark) {
        auto noise = cloud.add_flag(prop::kNoise);
        for (auto i : cloud.points)
            if (outside(i)) {
                noise[i] = 1;
                ++removed;
            }
    } else {
        const auto first_removed =
            std::stable_partition(cloud.points.begin(), cloud.points.end(),
                                  [&](PointSet::Index i) { return !outside(i); });
        removed = static_cast<std::size_t>(std::distance(first_removed, cloud.points.end()));
        if (removed > 0) {
            cloud.points.remove(first_removed, cloud.points.end());
            cloud.points.collect_garbage();
        }
    }
    return {{"crop_centre_m", {centre_world.x(), centre_world.y(), centre_world.z()}},
            {"crop_radius_m", radius_m},
            {"removed", removed}};
}

}  // namespace rgbd::frames
