#include "algorithms/evaluation/metrics.hpp"

#include <CGAL/AABB_face_graph_triangle_primitive.h>
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>

#include "algorithms/internal/cell_grid.hpp"
#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/internal/spatial_order.hpp"
#include "toolkit/error.hpp"
#include "toolkit/order_statistics.hpp"
#include "toolkit/random.hpp"

namespace rgbd::evaluation {

namespace {

using FaceIndex = Mesh::Face_index;
using Primitive = CGAL::AABB_face_graph_triangle_primitive<Mesh>;
using AabbTraits = CGAL::AABB_traits<Kernel, Primitive>;
using AabbTree = CGAL::AABB_tree<AabbTraits>;

/// Triangles of a mesh with positive area, their unit normals and cumulative areas.
struct Triangles {
    std::vector<FaceIndex> faces;
    std::vector<std::array<Eigen::Vector3d, 3>> corners;
    std::vector<Eigen::Vector3d> normals;
    std::vector<double> cumulative_area;  ///< cumulative_area[i] = area of faces 0..i
    double total_area() const { return cumulative_area.empty() ? 0.0 : cumulative_area.back(); }
};

Triangles collect_triangles(const Mesh& mesh, const char* what) {
    RGBD_CHECK(mesh.number_of_faces() > 0, std::string(what) + " mesh has no faces");
    Triangles t;
    double total = 0.0;
    for (FaceIndex f : mesh.faces()) {
        std::array<Eigen::Vector3d, 3> c;
        int i = 0;
        for (auto v : CGAL::vertices_around_face(mesh.halfedge(f), mesh)) {
            RGBD_CHECK(i < 3, std::string(what) + " mesh has a non-triangle face");
            c[i++] = to_eigen(mesh.point(v));
        }
        RGBD_CHECK(i == 3, std::string(what) + " mesh has a non-triangle face");
        for (const auto& p : c)
            RGBD_CHECK(p.allFinite(), std::string(what) + " mesh has a non-finite vertex");
        const Eigen::Vector3d cross = (c[1] - c[0]).cross(c[2] - c[0]);
        const double area = 0.5 * cross.norm();
        if (!(area > 0.0)) continue;  // zero-area triangle: no samples, not in the tree
        total += area;
        t.faces.push_back(f);
        t.corners.push_back(c);
        t.normals.push_back(cross.normalized());
        t.cumulative_area.push_back(total);
    }
    RGBD_CHECK(total > 0.0, std::string(what) + " mesh has no triangle of positive area");
    return t;
}

/// Area-uniform samples; face_of[i] = index into t.faces of sample i.
void sample_triangles(const Triangles& t, std::size_t count, std::uint64_t seed,
                      std::vector<Eigen::Vector3d>& points, std::vector<std::uint32_t>& face_of) {
    points.resize(count);
    face_of.resize(count);
    const double total = t.total_area();
    const std::uint64_t base = splitmix64(seed ^ 0x5DEECE66Dull);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, 4096),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t i = r.begin(); i != r.end(); ++i) {
                              std::uint64_t state = base + 3 * static_cast<std::uint64_t>(i);
                              const double a = unit_interval(splitmix64(state)) * total;
                              const double r1 = unit_interval(splitmix64(state + 1));
                              const double r2 = unit_interval(splitmix64(state + 2));
                              auto it = std::upper_bound(t.cumulative_area.begin(),
                                                         t.cumulative_area.end(), a);
                              if (it == t.cumulative_area.end()) --it;
                              const std::size_t f = it - t.cumulative_area.begin();
                              const auto& c = t.corners[f];
                              const double s = std::sqrt(r1);
                              points[i] = (1.0 - s) * c[0] + s * (1.0 - r2) * c[1] + s * r2 * c[2];
                              face_of[i] = static_cast<std::uint32_t>(f);
                          }
                      });
}

/// The sample indices 0 .. count - 1 ordered by the face they lie on (`face_of`; identity
/// when it is empty), ties by index.
std::vector<std::uint32_t> by_face(const std::vector<std::uint32_t>& face_of, std::size_t count) {
    std::vector<std::uint32_t> order(count);
    std::iota(order.begin(), order.end(), 0u);
    if (face_of.size() == count)
        std::stable_sort(order.begin(), order.end(),
                         [&](std::uint32_t a, std::uint32_t b) { return face_of[a] < face_of[b]; });
    return order;
}

/// AABB tree over the positive-area triangles of a mesh, ready for parallel queries.
struct MeshDistance {
    const Triangles& tri;
    AabbTree tree;
    std::vector<std::uint32_t> slot;  // face index -> index in tri

    MeshDistance(const Mesh& mesh, const Triangles& t)
        : tri(t), tree(t.faces.begin(), t.faces.end(), mesh) {
        tree.build();
        tree.accelerate_distance_queries();
        slot.assign(mesh.num_faces(), 0);  // num_faces() counts removed faces too
        for (std::uint32_t i = 0; i < t.faces.size(); ++i) slot[std::size_t(t.faces[i])] = i;
    }
    /// Distance to the surface and the index (in tri) of the closest triangle.
    double query(const Eigen::Vector3d& q, std::uint32_t& triangle) const {
        const auto hit = tree.closest_point_and_primitive(to_point(q));
        triangle = slot[std::size_t(hit.second)];
        return (to_eigen(hit.first) - q).norm();
    }
};

DistanceStats stats(std::vector<double> d) {
    DistanceStats s;
    if (d.empty()) return s;
    double sum = 0.0;
    for (double x : d) sum += x;  // sequential: same result for any thread count
    s.mean = sum / double(d.size());
    s.max = *std::max_element(d.begin(), d.end());
    s.median = lower_median(d);
    const std::size_t rank = static_cast<std::size_t>(std::ceil(0.95 * double(d.size())));
    s.p95 = kth_smallest(d, std::max<std::size_t>(rank, 1) - 1);
    return s;
}

/// Writes `s` into `j` as <name>_mean_m, <name>_median_m, <name>_p95_m and <name>_max_m.
void put_stats(Report& j, const std::string& name, const DistanceStats& s) {
    j[name + "_mean_m"] = s.mean;
    j[name + "_median_m"] = s.median;
    j[name + "_p95_m"] = s.p95;
    j[name + "_max_m"] = s.max;
}

double share_within(const std::vector<double>& d, double tau) {
    if (d.empty()) return 0.0;
    std::size_t n = 0;
    for (double x : d) n += x <= tau;
    return double(n) / double(d.size());
}

std::string tau_key(double tau_m) {
    const double mm = std::round(tau_m * 1e6) / 1e3;
    char buffer[64];
    if (mm == std::floor(mm)) {
        std::snprintf(buffer, sizeof buffer, "%.0fmm", mm);
    } else {
        std::snprintf(buffer, sizeof buffer, "%gmm", mm);
        for (char* c = buffer; *c; ++c)
            if (*c == '.') *c = 'p';
    }
    return buffer;
}

}  // namespace

void MetricOptions::check() const {
    RGBD_CHECK(!taus_m.empty(), "metrics: at least one threshold tau is needed");
    for (double t : taus_m)
        RGBD_CHECK(std::isfinite(t) && t > 0.0, "metrics: thresholds tau must be positive");
    check_range("metrics: samples", samples, Range::closed(1, 100000000));
    RGBD_CHECK(std::isfinite(invented_tau_m) && invented_tau_m > 0.0,
               "metrics: invented_tau_m must be positive");
}

std::vector<Eigen::Vector3d> sample_surface(const Mesh& mesh, std::size_t count,
                                            std::uint64_t seed) {
    const Triangles t = collect_triangles(mesh, "sampled");
    std::vector<Eigen::Vector3d> points;
    std::vector<std::uint32_t> faces;
    sample_triangles(t, count, seed, points, faces);
    return points;
}

SurfaceMetrics compare_to_reference(const Mesh* result_mesh, const PointCloud* result_points,
                                    const Mesh& reference, const MetricOptions& options) {
    Stopwatch watch;
    options.check();
    RGBD_CHECK(result_mesh || result_points, "metrics: no result mesh or cloud given");
    const Triangles ref_tri = collect_triangles(reference, "reference");
    const MeshDistance ref_dist(reference, ref_tri);

    // Reference samples (seed distinct from the result's).
    std::vector<Eigen::Vector3d> ref_samples;
    std::vector<std::uint32_t> ref_face;
    sample_triangles(ref_tri, options.samples, options.seed * 2 + 1, ref_samples, ref_face);

    // Result samples with their normals (when known).
    std::vector<Eigen::Vector3d> res_samples;
    std::vector<Eigen::Vector3d> res_normals;  // empty = no normals
    std::optional<Triangles> res_tri;
    std::optional<MeshDistance> res_dist;
    std::vector<Eigen::Vector3d> cloud_normals;
    std::vector<std::uint32_t> res_face;  // empty for a result cloud
    if (result_mesh) {
        res_tri.emplace(collect_triangles(*result_mesh, "result"));
        sample_triangles(*res_tri, options.samples, options.seed * 2, res_samples, res_face);
        res_normals.resize(res_samples.size());
        for (std::size_t i = 0; i < res_samples.size(); ++i)
            res_normals[i] = res_tri->normals[res_face[i]];
        res_dist.emplace(*result_mesh, *res_tri);
    } else {
        RGBD_CHECK(!result_points->empty(), "metrics: the result cloud is empty");
        const bool normals = result_points->points.has_normal_map();
        for (PointSet::Index idx : result_points->points) {
            const Eigen::Vector3d p = to_eigen(result_points->points.point(idx));
            RGBD_CHECK(p.allFinite(), "metrics: view " + std::to_string(result_points->view.id) +
                                          ": the result cloud has a non-finite point");
            res_samples.push_back(p);
            if (normals) {
                const Eigen::Vector3d n = to_eigen(result_points->points.normal(idx));
                res_normals.push_back(n.norm() > 0 ? n.normalized() : n);
            }
        }
        cloud_normals = res_normals;
    }

    // Result -> reference. The samples are drawn in random order; the queries run in the order
    // of the faces they lie on, which are neighbours in the mesh's storage, so that successive
    // queries walk the same branches of the tree (each query's answer does not depend on it).
    const std::size_t nr = res_samples.size();
    std::vector<double> acc(nr);
    std::vector<double> acc_normal(res_normals.empty() ? 0 : nr);
    const std::vector<std::uint32_t> res_order = by_face(res_face, nr);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nr, 1024),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t k = r.begin(); k != r.end(); ++k) {
                              const std::size_t i = res_order[k];
                              std::uint32_t tri = 0;
                              acc[i] = ref_dist.query(res_samples[i], tri);
                              if (!acc_normal.empty())
                                  acc_normal[i] =
                                      std::abs(res_normals[i].dot(ref_tri.normals[tri]));
                          }
                      });

    // Reference -> result.
    const std::size_t ns = ref_samples.size();
    std::vector<double> comp(ns);
    std::vector<double> comp_normal(res_normals.empty() ? 0 : ns);
    if (res_dist) {
        const std::vector<std::uint32_t> ref_order = by_face(ref_face, ns);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, ns, 1024),
                          [&](const tbb::blocked_range<std::size_t>& r) {
                              for (std::size_t k = r.begin(); k != r.end(); ++k) {
                                  const std::size_t i = ref_order[k];
                                  std::uint32_t tri = 0;
                                  comp[i] = res_dist->query(ref_samples[i], tri);
                                  comp_normal[i] = std::abs(
                                      ref_tri.normals[ref_face[i]].dot(res_tri->normals[tri]));
                              }
                          });
    } else {
        const internal::KdTree tree(res_samples);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, ns, 1024),
                          [&](const tbb::blocked_range<std::size_t>& r) {
                              for (std::size_t i = r.begin(); i != r.end(); ++i) {
                                  std::uint32_t j = 0;
                                  double sq = 0.0;
                                  tree.nearest(ref_samples[i], j, sq);
                                  comp[i] = std::sqrt(sq);
                                  if (!comp_normal.empty())
                                      comp_normal[i] = std::abs(
                                          ref_tri.normals[ref_face[i]].dot(cloud_normals[j]));
                              }
                          });
    }

    SurfaceMetrics m;
    m.result_samples = nr;
    m.reference_samples = ns;
    for (double tau : options.taus_m) {
        ThresholdScores s;
        s.tau_m = tau;
        s.precision = share_within(acc, tau);
        s.recall = share_within(comp, tau);
        s.fscore = s.precision + s.recall > 0.0
                       ? 2.0 * s.precision * s.recall / (s.precision + s.recall)
                       : 0.0;
        m.thresholds.push_back(s);
    }
    m.invented_tau_m = options.invented_tau_m;
    m.invented_surface_fraction = 1.0 - share_within(acc, options.invented_tau_m);
    if (!acc_normal.empty()) {
        const double a = std::accumulate(acc_normal.begin(), acc_normal.end(), 0.0);
        const double b = std::accumulate(comp_normal.begin(), comp_normal.end(), 0.0);
        m.normal_consistency = 0.5 * (a / double(nr) + b / double(ns));
    }
    m.accuracy = stats(std::move(acc));
    m.completeness = stats(std::move(comp));
    m.chamfer_m = 0.5 * (m.accuracy.mean + m.completeness.mean);
    m.hausdorff_m = std::max(m.accuracy.max, m.completeness.max);
    m.hausdorff_p95_m = std::max(m.accuracy.p95, m.completeness.p95);
    m.time_s = watch.seconds();
    return m;
}

Report SurfaceMetrics::to_json() const {
    Report j;
    j["chamfer_m"] = chamfer_m;
    j["hausdorff_m"] = hausdorff_m;
    j["hausdorff_p95_m"] = hausdorff_p95_m;
    put_stats(j, "accuracy", accuracy);
    put_stats(j, "completeness", completeness);
    for (const ThresholdScores& s : thresholds) {
        const std::string key = tau_key(s.tau_m);
        j["precision_" + key] = s.precision;
        j["recall_" + key] = s.recall;
        j["fscore_" + key] = s.fscore;
    }
    j["invented_tau_m"] = invented_tau_m;
    j["invented_surface_fraction"] = invented_surface_fraction;
    j["normal_consistency"] =
        normal_consistency ? nlohmann::json(*normal_consistency) : nlohmann::json(nullptr);
    j["result_samples"] = result_samples;
    j["reference_samples"] = reference_samples;
    j["time_s"] = time_s;
    return j;
}

PoseErrors pose_errors(const std::map<std::string, Pose>& estimated,
                       const std::map<std::string, Pose>& truth, bool remove_gauge) {
    std::vector<std::string> common;
    PoseErrors out;
    for (const auto& [sensor, pose] : truth) {
        RGBD_CHECK(pose.matrix().allFinite(),
                   "pose errors: true pose of sensor " + sensor + " is not finite");
        auto it = estimated.find(sensor);
        if (it == estimated.end()) {
            out.missing.push_back(sensor);
            continue;
        }
        RGBD_CHECK(it->second.matrix().allFinite(),
                   "pose errors: estimated pose of sensor " + sensor + " is not finite");
        common.push_back(sensor);
    }
    RGBD_CHECK(!common.empty(), "pose errors: no sensor has both an estimate and a true pose");

    out.gauge_removed = remove_gauge;
    if (remove_gauge) {
        bool umeyama_ok = false;
        if (common.size() >= 3) {
            Eigen::Matrix3Xd src(3, common.size()), dst(3, common.size());
            for (std::size_t i = 0; i < common.size(); ++i) {
                src.col(i) = estimated.at(common[i]).translation();
                dst.col(i) = truth.at(common[i]).translation();
            }
            const Eigen::Matrix3Xd centred = src.colwise() - src.rowwise().mean();
            const Eigen::JacobiSVD<Eigen::Matrix3Xd> svd(centred);
            const Eigen::Vector3d sv = svd.singularValues();
            if (sv(0) > 0.0 && sv(1) > 1e-6 * sv(0)) {
                out.truth_from_estimate.matrix() = Eigen::umeyama(src, dst, false);
                out.gauge_method = "umeyama";
                umeyama_ok = true;
            }
        }
        if (!umeyama_ok) {
            out.truth_from_estimate =
                truth.at(common.front()) * estimated.at(common.front()).inverse();
            out.gauge_method = "first_pose";
        }
    }

    double sum_r = 0.0, sum_t = 0.0;
    for (const std::string& sensor : common) {
        const Pose aligned = out.truth_from_estimate * estimated.at(sensor);
        PoseError e;
        e.sensor = sensor;
        e.rotation_deg = rotation_error_deg(aligned, truth.at(sensor));
        e.translation_mm = 1000.0 * translation_error_m(aligned, truth.at(sensor));
        sum_r += e.rotation_deg;
        sum_t += e.translation_mm;
        out.max_rotation_deg = std::max(out.max_rotation_deg, e.rotation_deg);
        out.max_translation_mm = std::max(out.max_translation_mm, e.translation_mm);
        out.per_sensor.push_back(e);
    }
    out.mean_rotation_deg = sum_r / double(common.size());
    out.mean_translation_mm = sum_t / double(common.size());
    return out;
}

Report PoseErrors::to_json() const {
    Report j;
    j["mean_rotation_deg"] = mean_rotation_deg;
    j["max_rotation_deg"] = max_rotation_deg;
    j["mean_translation_mm"] = mean_translation_mm;
    j["max_translation_mm"] = max_translation_mm;
    j["gauge_removed"] = gauge_removed;
    j["gauge_method"] = gauge_method;
    Report per = Report::object();
    for (const PoseError& e : per_sensor)
        per[e.sensor] = {{"rotation_deg", e.rotation_deg}, {"translation_mm", e.translation_mm}};
    j["per_sensor"] = per;
    j["missing"] = missing;
    return j;
}

std::vector<double> distances_to_surface(const std::vector<Eigen::Vector3d>& points,
                                         const Mesh& reference) {
    for (const auto& p : points) RGBD_CHECK(p.allFinite(), "distance query of a non-finite point");
    const Triangles tri = collect_triangles(reference, "reference");
    const MeshDistance dist(reference, tri);
    std::vector<double> out(points.size());
    const std::vector<std::uint32_t> order = internal::spatial_order(points);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size(), 1024),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t k = r.begin(); k != r.end(); ++k) {
                              const std::size_t i = order[k];
                              std::uint32_t t = 0;
                              out[i] = dist.query(points[i], t);
                          }
                      });
    return out;
}

std::vector<double> distances_to_points(const std::vector<Eigen::Vector3d>& points,
                                        const std::vector<Eigen::Vector3d>& cloud) {
    RGBD_CHECK(!cloud.empty(), "distance query against an empty cloud");
    for (const auto& p : points) RGBD_CHECK(p.allFinite(), "distance query of a non-finite point");
    for (const auto& p : cloud) RGBD_CHECK(p.allFinite(), "cloud has a non-finite point");
    // A cell grid, not a kd-tree: the cloud is often millions of points (a merged sequence)
    // against a few hundred thousand queries, and a kd-tree's build is sequential.
    // In space order, the previous query's nearest point bounds this one's distance: queries
    // far from the cloud (a closure's vertices) search a few cells instead of whole rings.
    const internal::PointSearch search(cloud);
    std::vector<double> out(points.size());
    const std::vector<std::uint32_t> order = internal::spatial_order(points);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size(), 1024),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          std::uint32_t last = 0;
                          bool have = false;
                          for (std::size_t k = r.begin(); k != r.end(); ++k) {
                              const std::size_t i = order[k];
                              std::uint32_t j = 0;
                              double sq = 0.0;
                              const double bound =
                                  internal::knn_bound(cloud, &last, have ? 1 : 0, points[i]);
                              have = search.knn(points[i], 1, &j, &sq, bound) == 1;
                              last = j;
                              out[i] = std::sqrt(sq);
                          }
                      });
    return out;
}

std::vector<char> within_distance(const std::vector<Eigen::Vector3d>& points,
                                  const std::vector<Eigen::Vector3d>& cloud, double tau) {
    RGBD_CHECK(!cloud.empty(), "distance query against an empty cloud");
    RGBD_CHECK(std::isfinite(tau) && tau > 0, "distance query: the distance must be positive");
    for (const auto& p : points) RGBD_CHECK(p.allFinite(), "distance query of a non-finite point");
    for (const auto& p : cloud) RGBD_CHECK(p.allFinite(), "cloud has a non-finite point");
    std::vector<char> out(points.size(), 0);
    internal::CellGrid grid;
    if (!grid.build(cloud, tau)) {  // an extent beyond 21 bits of cells of tau
        const std::vector<double> d = distances_to_points(points, cloud);
        for (std::size_t i = 0; i < d.size(); ++i) out[i] = d[i] <= tau;
        return out;
    }
    const std::vector<std::uint32_t> order = internal::spatial_order(points);
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, points.size(), 1024),
        [&](const tbb::blocked_range<std::size_t>& r) {
            for (std::size_t k = r.begin(); k != r.end(); ++k) {
                const std::size_t i = order[k];
                const Eigen::Vector3d& q = points[i];
                if (!(((q - grid.lowest()) / tau).cwiseAbs().maxCoeff() < 1e15)) continue;
                const auto c = grid.cell_of(q);
                bool found = false;
                for (std::int64_t x = c.x() - 1; x <= c.x() + 1 && !found; ++x)
                    for (std::int64_t y = c.y() - 1; y <= c.y() + 1 && !found; ++y) {
                        const auto [c0, c1] = grid.column(x, y, c.z() - 1, c.z() + 1);
                        for (std::uint32_t a = grid.start[c0]; a < grid.start[c1]; ++a)
                            // sqrt as distances_to_points takes it: the same answer at tau
                            if (std::sqrt((cloud[grid.point[a]] - q).squaredNorm()) <= tau) {
                                found = true;
                                break;
                            }
                    }
                out[i] = found ? 1 : 0;
            }
        });
    return out;
}

}  // namespace rgbd::evaluation
