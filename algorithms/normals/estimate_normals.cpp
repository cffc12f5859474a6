#include "algorithms/normals/estimate_normals.hpp"

#include <CGAL/mst_orient_normals.h>
#include <CGAL/property_map.h>
#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "algorithms/internal/kd_tree.hpp"
#include "toolkit/enum_names.hpp"
#include "toolkit/error.hpp"

namespace rgbd::normals {

namespace {
constexpr EnumName<NormalOrientation> kOrientationNames[] = {
    {NormalOrientation::kAuto, "auto"},
    {NormalOrientation::kSensor, "sensor"},
    {NormalOrientation::kMst, "mst"},
    {NormalOrientation::kOutward, "outward"},
    {NormalOrientation::kNone, "none"}};
}  // namespace

const char* to_string(NormalOrientation orientation) {
    return name_of(kOrientationNames, orientation);
}

void NormalOptions::check() const {
    RGBD_CHECK(k >= 3 && k <= 1024, "normals: k must be in [3, 1024], got " + std::to_string(k));
    RGBD_CHECK(mst_k >= 2 && mst_k <= 1024,
               "normals: mst_k must be in [2, 1024], got " + std::to_string(mst_k));
    for (const auto& [id, centre] : sensor_centres)
        RGBD_CHECK(centre.allFinite(),
                   "normals: sensor centre of view " + std::to_string(id) + " is not finite");
}

namespace {

constexpr std::size_t kChunk = 1024;

std::string view_name(const PointCloud& cloud) { return "view " + std::to_string(cloud.view.id); }

/// Sensor centre of a single-sensor view in the cloud's own frame, if known.
std::optional<Eigen::Vector3d> view_sensor_centre(const PointCloud& cloud) {
    if (cloud.view.frame == ViewFrame::kSensor) return Eigen::Vector3d::Zero();
    if (cloud.view.world_from_sensor) return cloud.view.world_from_sensor->translation();
    return std::nullopt;
}

void orient_mst(const std::vector<Eigen::Vector3d>& xyz, std::vector<Eigen::Vector3d>& normals,
                int mst_k, std::size_t& unoriented) {
    std::vector<Point_3> pts(xyz.size());
    std::vector<Vector_3> nrm(xyz.size());
    for (std::size_t i = 0; i < xyz.size(); ++i) {
        pts[i] = to_point(xyz[i]);
        nrm[i] = to_vector(normals[i]);
    }
    std::vector<std::size_t> order(xyz.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    auto first_unoriented =
        CGAL::mst_orient_normals(order, static_cast<unsigned int>(mst_k),
                                 CGAL::parameters::point_map(CGAL::make_property_map(pts))
                                     .normal_map(CGAL::make_property_map(nrm)));
    // Leftovers (other connected components) are oriented away from the centroid.
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const auto& p : xyz) centroid += p;
    centroid /= static_cast<double>(xyz.size());
    std::vector<char> oriented(xyz.size(), 1);
    for (auto it = first_unoriented; it != order.end(); ++it) oriented[*it] = 0;
    unoriented = static_cast<std::size_t>(order.end() - first_unoriented);
    for (std::size_t i = 0; i < xyz.size(); ++i) {
        Eigen::Vector3d n = to_eigen(nrm[i]);
        if (!oriented[i] && n.dot(xyz[i] - centroid) < 0) n = -n;
        normals[i] = n;
    }
}

}  // namespace

Report estimate_normals(PointCloud& cloud, const NormalOptions& options, const Progress& progress) {
    options.check();
    Stopwatch watch;
    const std::size_t n = cloud.size();
    RGBD_CHECK(n >= 3, "normals: " + view_name(cloud) + ": needs at least 3 points, got " +
                           std::to_string(n));

    std::vector<PointSet::Index> index;
    std::vector<Eigen::Vector3d> xyz;
    index.reserve(n);
    xyz.reserve(n);
    for (auto idx : cloud.points) {
        const Eigen::Vector3d p = to_eigen(cloud.points.point(idx));
        RGBD_CHECK(p.allFinite(), "normals: " + view_name(cloud) + ": point " +
                                      std::to_string(xyz.size()) + " is not finite");
        index.push_back(idx);
        xyz.push_back(p);
    }

    // Resolve the orientation rule.
    NormalOrientation rule = options.orientation;
    const std::optional<Eigen::Vector3d> centre = view_sensor_centre(cloud);
    const auto view_ids = cloud.view_map();
    const bool per_view = !options.sensor_centres.empty() && view_ids.has_value();
    if (rule == NormalOrientation::kAuto)
        rule = (per_view || centre) ? NormalOrientation::kSensor : NormalOrientation::kMst;
    RGBD_CHECK(rule != NormalOrientation::kSensor || per_view || centre,
               "normals: " + view_name(cloud) +
                   ": orientation 'sensor' needs a sensor-frame view, a world_from_sensor pose "
                   "or sensor_centres with a view property");

    // PCA per point, fixed chunks; each point's result depends only on its neighbourhood.
    const internal::KdTree tree(xyz);
    const std::size_t k = std::min<std::size_t>(static_cast<std::size_t>(options.k), n);
    std::vector<Eigen::Vector3d> normals(n);
    std::vector<char> degenerate(n, 0);
    const std::size_t chunks = (n + kChunk - 1) / kChunk;
    std::atomic<bool> cancelled{false};
    std::atomic<std::size_t> done{0};
    tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) {
        if (cancelled.load(std::memory_order_relaxed)) return;
        std::vector<std::uint32_t> nn(k);
        std::vector<double> sq(k);
        const std::size_t begin = c * kChunk, end = std::min(n, begin + kChunk);
        for (std::size_t i = begin; i < end; ++i) {
            const std::size_t found = tree.knn(xyz[i], k, nn.data(), sq.data());
            Eigen::Vector3d mean = Eigen::Vector3d::Zero();
            for (std::size_t j = 0; j < found; ++j) mean += xyz[nn[j]];
            mean /= static_cast<double>(found);
            Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
            for (std::size_t j = 0; j < found; ++j) {
                const Eigen::Vector3d d = xyz[nn[j]] - mean;
                cov.noalias() += d * d.transpose();
            }
            Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
            Eigen::Vector3d normal = eig.eigenvectors().col(0);
            const Eigen::Vector3d ev = eig.eigenvalues();
            if (found < 3 || !normal.allFinite() || ev(1) <= 1e-14 * std::max(ev(2), 1e-300)) {
                degenerate[i] = 1;  // collinear or coincident neighbours
                if (!normal.allFinite()) normal = Eigen::Vector3d::UnitZ();
            }
            // Deterministic PCA sign before orientation: largest component positive.
            Eigen::Index arg;
            normal.cwiseAbs().maxCoeff(&arg);
            if (normal(arg) < 0) normal = -normal;
            normals[i] = normal.normalized();
        }
        const std::size_t so_far = done.fetch_add(end - begin) + (end - begin);
        if (progress && c % 16 == 0 && !report_progress(progress, 0.9 * so_far / n))
            cancelled = true;
    });
    if (cancelled) throw AlgorithmError("normals: " + view_name(cloud) + ": cancelled");

    std::size_t flipped = 0, unoriented = 0;
    if (rule == NormalOrientation::kSensor || rule == NormalOrientation::kOutward) {
        Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
        for (const auto& p : xyz) centroid += p;
        centroid /= static_cast<double>(n);
        for (std::size_t i = 0; i < n; ++i) {
            bool flip = false;
            if (rule == NormalOrientation::kOutward) {
                flip = normals[i].dot(xyz[i] - centroid) < 0;
            } else {
                const Eigen::Vector3d* c = centre ? &*centre : nullptr;
                if (per_view) {
                    auto it = options.sensor_centres.find((*view_ids)[index[i]]);
                    if (it != options.sensor_centres.end()) c = &it->second;
                }
                if (c)
                    flip = normals[i].dot(*c - xyz[i]) < 0;
                else
                    ++unoriented;
            }
            if (flip) {
                normals[i] = -normals[i];
                ++flipped;
            }
        }
    } else if (rule == NormalOrientation::kMst) {
        orient_mst(xyz, normals, options.mst_k, unoriented);
    }

    if (!cloud.points.has_normal_map()) cloud.points.add_normal_map();
    for (std::size_t i = 0; i < n; ++i) cloud.points.normal(index[i]) = to_vector(normals[i]);
    report_progress(progress, 1.0);

    std::size_t degenerate_count = 0;
    for (char d : degenerate) degenerate_count += d ? 1 : 0;
    Report report;
    report["k"] = options.k;
    report["orientation"] = to_string(rule);
    report["points"] = n;
    report["flipped"] = flipped;
    report["unoriented"] = unoriented;
    report["degenerate"] = degenerate_count;
    report["time_s"] = watch.seconds();
    return report;
}

}  // namespace rgbd::normals
