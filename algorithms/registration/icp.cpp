#include "algorithms/registration/icp.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/internal/pair_icp.hpp"
#include "algorithms/sampling/robust_spacing.hpp"
#include "toolkit/error.hpp"

namespace rgbd::registration {

namespace {

constexpr double kDegToRad = M_PI / 180.0;

std::string view_name(const PointCloud& cloud) { return "view " + std::to_string(cloud.view.id); }

struct Gathered {
    std::vector<Eigen::Vector3d> xyz;
    std::vector<Eigen::Vector3d> normals;  // empty when the cloud has none
};

Gathered gather(const PointCloud& cloud, const char* role) {
    Gathered g;
    const bool normals = cloud.points.has_normal_map();
    g.xyz.reserve(cloud.size());
    if (normals) g.normals.reserve(cloud.size());
    for (auto idx : cloud.points) {
        const Eigen::Vector3d p = to_eigen(cloud.points.point(idx));
        RGBD_CHECK(p.allFinite(), std::string("icp: ") + role + " " + view_name(cloud) +
                                      ": point " + std::to_string(g.xyz.size()) + " is not finite");
        g.xyz.push_back(p);
        if (normals) {
            const Eigen::Vector3d n = to_eigen(cloud.points.normal(idx));
            RGBD_CHECK(n.allFinite(), std::string("icp: ") + role + " " + view_name(cloud) +
                                          ": normal " + std::to_string(g.normals.size()) +
                                          " is not finite");
            const double len = n.norm();
            g.normals.push_back(len > 0 ? Eigen::Vector3d(n / len) : n);
        }
    }
    return g;
}

}  // namespace

void IcpCriteria::check() const {
    check_range("icp: max_iterations", max_iterations, Range::closed(1, 100000));
    RGBD_CHECK(relative_fitness >= 0 && relative_rmse >= 0 && min_rotation_deg >= 0 &&
                   min_translation_spacing >= 0,
               "icp: convergence thresholds must be non-negative");
}

void IcpOptions::check() const {
    criteria.check();
    for (double d : max_distances_m)
        RGBD_CHECK(std::isfinite(d) && d > 0, "icp: max distances must be positive");
    RGBD_CHECK(!max_distances_m.empty() || !max_distance_factors.empty(),
               "icp: give max_distances_m or max_distance_factors");
    for (double f : max_distance_factors)
        check_range("icp: max distance factors", f, Range::open(0, 1e4));
    RGBD_CHECK(std::isfinite(spacing_m) && spacing_m >= 0, "icp: spacing_m must be >= 0");
    check_range("icp: kernel_scale", kernel_scale, Range::open_closed(0, 100));
    check_range("icp: max_normal_angle_deg", max_normal_angle_deg, Range::open_closed(0, 360));
}

Report AlignResult::to_json() const {
    return Report{{"target_from_source", pose_to_3x4(target_from_source)},
                  {"fitness", fitness},
                  {"inlier_rmse_m", inlier_rmse},
                  {"plane_rmse_m", plane_rmse},
                  {"correspondences", correspondences},
                  {"iterations", iterations},
                  {"converged", converged}};
}

AlignResult align_pair(const PointCloud& source, const PointCloud& target,
                       const Pose& initial_target_from_source, const IcpOptions& options) {
    options.check();
    RGBD_CHECK(!source.empty(), "icp: source " + view_name(source) + " is empty");
    RGBD_CHECK(!target.empty(), "icp: target " + view_name(target) + " is empty");
    RGBD_CHECK(target.points.has_normal_map(),
               "icp: target " + view_name(target) + " has no normals; estimate them first");
    RGBD_CHECK(initial_target_from_source.matrix().allFinite(),
               "icp: initial pose of source " + view_name(source) + " is not finite");
    Gathered src = gather(source, "source");
    Gathered tgt = gather(target, "target");

    double spacing = options.spacing_m;
    std::vector<double> distances = options.max_distances_m;
    if (spacing <= 0 && (distances.empty() || options.criteria.min_translation_spacing > 0))
        spacing = src.xyz.size() >= 2 ? sampling::robust_spacing(source.points) : 0.0;
    if (distances.empty()) {
        RGBD_CHECK(spacing > 0,
                   "icp: source " + view_name(source) + " has zero spacing; give max_distances_m");
        for (double f : options.max_distance_factors) distances.push_back(f * spacing);
    }

    internal::RegCloud src_reg, tgt_reg;
    src_reg.xyz = std::move(src.xyz);
    src_reg.normals = std::move(src.normals);
    for (const auto& p : src_reg.xyz) src_reg.centroid += p;
    src_reg.centroid /= static_cast<double>(src_reg.xyz.size());
    tgt_reg.xyz = std::move(tgt.xyz);
    tgt_reg.normals = std::move(tgt.normals);
    const internal::KdTree tree(tgt_reg.xyz);

    internal::PairIcpSettings settings;
    settings.distances = distances;
    settings.max_iterations = options.criteria.max_iterations;
    settings.kernel = static_cast<int>(options.kernel);
    settings.kernel_scale = options.kernel_scale;
    settings.cos_gate = options.max_normal_angle_deg >= 180
                            ? -2.0
                            : std::cos(options.max_normal_angle_deg * kDegToRad);
    settings.relative_fitness = options.criteria.relative_fitness;
    settings.relative_rmse = options.criteria.relative_rmse;
    settings.min_rotation_rad = options.criteria.min_rotation_deg * kDegToRad;
    settings.min_translation = options.criteria.min_translation_spacing * spacing;
    settings.stride_coarse_stages = false;
    // The outcome is an AlignResult plus what the ring alignment needs (colour, information).
    return internal::pair_icp(src_reg, tgt_reg, tree, initial_target_from_source, settings,
                              distances.back());
}

}  // namespace rgbd::registration
