#include "algorithms/evaluation/mesh_quality.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "algorithms/evaluation/metrics.hpp"
#include "algorithms/reconstruction/self_intersections.hpp"
#include "toolkit/error.hpp"

namespace rgbd::evaluation {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr std::size_t kNoSlot = static_cast<std::size_t>(-1);

/// "5deg", "7p5deg", "3mm", "0p5mm": a number with 'p' for the decimal point.
std::string number_key(double value, const char* unit) {
    char buffer[64];
    std::snprintf(buffer, sizeof buffer, "%g", std::round(value * 1e3) / 1e3);
    std::string s(buffer);
    std::replace(s.begin(), s.end(), '.', 'p');
    return s + unit;
}

/// Angle (radians) between two vectors, 0 when one of them is zero.
double angle_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    const double na = a.norm(), nb = b.norm();
    if (!(na > 0.0) || !(nb > 0.0)) return 0.0;
    return std::acos(std::clamp(a.dot(b) / (na * nb), -1.0, 1.0));
}

/// Per face: the area vector (cross product / 2) and the minimum interior angle (radians).
struct FaceGeometry {
    Eigen::Vector3d area_vector = Eigen::Vector3d::Zero();
    double area = 0.0;
    double min_angle = 0.0;
};

FaceGeometry face_geometry(const std::array<Eigen::Vector3d, 3>& c) {
    FaceGeometry g;
    g.area_vector = 0.5 * (c[1] - c[0]).cross(c[2] - c[0]);
    g.area = g.area_vector.norm();
    if (!(g.area > 0.0)) return g;  // degenerate: minimum angle 0
    double smallest = kPi;
    for (int i = 0; i < 3; ++i)
        smallest = std::min(smallest, angle_between(c[(i + 1) % 3] - c[i], c[(i + 2) % 3] - c[i]));
    g.min_angle = smallest;
    return g;
}

}  // namespace

void MeshQualityOptions::check() const {
    RGBD_CHECK(!sliver_angles_deg.empty(), "mesh quality: at least one sliver angle is needed");
    for (double a : sliver_angles_deg)
        check_range("mesh quality: sliver angles", a, Range::open_closed(0.0, 60.0), "degrees");
    check_range("mesh quality: fold_angle_deg", fold_angle_deg, Range::open(0.0, 180.0));
    check_range("mesh quality: spike_angle_deg", spike_angle_deg, Range::open(0.0, 180.0));
    RGBD_CHECK(std::isfinite(far_tau_m) && far_tau_m > 0.0,
               "mesh quality: far_tau_m must be positive");
    RGBD_CHECK(std::isfinite(grey_tau_m) && grey_tau_m > 0.0,
               "mesh quality: grey_tau_m must be positive");
    check_range("mesh quality: grey_tolerance", grey_tolerance, Range::closed(0, 255));
    check_range("mesh quality: samples", samples, Range::closed(1, 100000000));
}

Report mesh_quality(const Mesh& mesh, const std::vector<Eigen::Vector3d>* input_points,
                    const MeshQualityOptions& options) {
    options.check();
    const Stopwatch watch;
    RGBD_CHECK(mesh.number_of_faces() > 0, "mesh quality: the mesh has no faces");
    if (input_points) {
        RGBD_CHECK(!input_points->empty(), "mesh quality: the input points are empty");
    }

    // Faces: geometry in parallel (surface meshes may have removed elements: index by slot).
    const std::vector<Mesh::Face_index> faces(mesh.faces().begin(), mesh.faces().end());
    std::vector<std::array<Mesh::Vertex_index, 3>> face_vertices(faces.size());
    for (std::size_t i = 0; i < faces.size(); ++i) {
        int k = 0;
        for (auto v : CGAL::vertices_around_face(mesh.halfedge(faces[i]), mesh)) {
            RGBD_CHECK(k < 3, "mesh quality: the mesh has a non-triangle face");
            face_vertices[i][k++] = v;
        }
        RGBD_CHECK(k == 3, "mesh quality: the mesh has a non-triangle face");
    }
    for (auto v : mesh.vertices())
        RGBD_CHECK(to_eigen(mesh.point(v)).allFinite(), "mesh quality: non-finite vertex");
    std::vector<FaceGeometry> geometry(faces.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, faces.size(), 2048),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t i = r.begin(); i != r.end(); ++i) {
                              std::array<Eigen::Vector3d, 3> c;
                              for (int k = 0; k < 3; ++k)
                                  c[k] = to_eigen(mesh.point(face_vertices[i][k]));
                              geometry[i] = face_geometry(c);
                          }
                      });
    std::vector<std::size_t> slot(mesh.num_faces(), kNoSlot);  // counts removed faces too
    for (std::size_t i = 0; i < faces.size(); ++i) slot[std::size_t(faces[i])] = i;

    Report out = Report::object();
    out["faces"] = faces.size();
    out["vertices"] = mesh.number_of_vertices();
    double total_area = 0.0;
    for (const auto& g : geometry) total_area += g.area;  // sequential: deterministic
    out["area_m2"] = total_area;

    // Slivers.
    for (double deg : options.sliver_angles_deg) {
        const double limit = deg * kPi / 180.0;
        std::size_t count = 0;
        double area = 0.0;
        for (const auto& g : geometry)
            if (g.min_angle < limit) ++count, area += g.area;
        const std::string key = number_key(deg, "deg");
        out["sliver_fraction_" + key] = double(count) / double(faces.size());
        out["sliver_area_fraction_" + key] = total_area > 0.0 ? area / total_area : 0.0;
    }

    // Folds: edges with two positive-area faces.
    const double fold_cos = std::cos(options.fold_angle_deg * kPi / 180.0);
    const std::vector<Mesh::Edge_index> edges(mesh.edges().begin(), mesh.edges().end());
    std::vector<std::uint8_t> edge_state(edges.size(), 0);  // 0 boundary/degenerate, 1 ok, 2 fold
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, edges.size(), 4096),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t i = r.begin(); i != r.end(); ++i) {
                              const auto h = mesh.halfedge(edges[i]);
                              const auto f0 = mesh.face(h), f1 = mesh.face(mesh.opposite(h));
                              if (f0 == Mesh::null_face() || f1 == Mesh::null_face()) continue;
                              const FaceGeometry& g0 = geometry[slot[std::size_t(f0)]];
                              const FaceGeometry& g1 = geometry[slot[std::size_t(f1)]];
                              if (!(g0.area > 0.0) || !(g1.area > 0.0)) continue;
                              const double c =
                                  g0.area_vector.dot(g1.area_vector) / (g0.area * g1.area);
                              edge_state[i] = c < fold_cos ? 2 : 1;
                          }
                      });
    std::size_t interior = 0, folds = 0;
    for (auto s : edge_state) interior += s != 0, folds += s == 2;
    out["edges_interior"] = interior;
    out["fold_edges"] = folds;
    out["fold_edge_fraction"] = interior ? double(folds) / double(interior) : 0.0;

    // Spikes: face normals against the area-weighted vertex normal.
    const double spike_cos = std::cos(options.spike_angle_deg * kPi / 180.0);
    const std::vector<Mesh::Vertex_index> vertices(mesh.vertices().begin(), mesh.vertices().end());
    std::vector<std::uint8_t> vertex_state(vertices.size(), 0);  // 0 no face, 1 ok, 2 spike
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, vertices.size(), 2048),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t i = r.begin(); i != r.end(); ++i) {
                              const auto h = mesh.halfedge(vertices[i]);
                              if (h == Mesh::null_halfedge()) continue;  // isolated vertex
                              Eigen::Vector3d sum = Eigen::Vector3d::Zero();
                              double area_sum = 0.0;
                              for (auto f : CGAL::faces_around_target(h, mesh)) {
                                  if (f == Mesh::null_face()) continue;
                                  const FaceGeometry& g = geometry[slot[std::size_t(f)]];
                                  sum += g.area_vector;
                                  area_sum += g.area;
                              }
                              if (!(area_sum > 0.0)) continue;
                              const double norm = sum.norm();
                              bool spike = !(norm > 1e-9 * area_sum);
                              if (!spike)
                                  for (auto f : CGAL::faces_around_target(h, mesh)) {
                                      if (f == Mesh::null_face()) continue;
                                      const FaceGeometry& g = geometry[slot[std::size_t(f)]];
                                      if (!(g.area > 0.0)) continue;
                                      if (g.area_vector.dot(sum) / (g.area * norm) < spike_cos) {
                                          spike = true;
                                          break;
                                      }
                                  }
                              vertex_state[i] = spike ? 2 : 1;
                          }
                      });
    std::size_t with_faces = 0, spikes = 0;
    for (auto s : vertex_state) with_faces += s != 0, spikes += s == 2;
    out["spike_vertices"] = spikes;
    out["spike_vertex_fraction"] = with_faces ? double(spikes) / double(with_faces) : 0.0;

    out["fold_angle_deg"] = options.fold_angle_deg;
    out["spike_angle_deg"] = options.spike_angle_deg;

    if (input_points) {
        for (const auto& p : *input_points)
            RGBD_CHECK(p.allFinite(), "mesh quality: non-finite input point");
        // Far area: area-uniform samples to the nearest input point. Grey vertices near
        // observed points. One distance query for both when their distances agree (the input
        // points' cell grid is built once).
        const std::string far_key =
            "far_area_fraction_" + number_key(options.far_tau_m * 1e3, "mm");
        std::vector<Eigen::Vector3d> samples;
        if (total_area > 0.0) samples = sample_surface(mesh, options.samples, options.seed);
        const auto colors = vertex_colors(mesh);
        std::vector<Eigen::Vector3d> grey;
        if (colors && !vertices.empty()) {
            auto near_fill = [&](unsigned char c) {
                return std::abs(int(c) - int(options.grey_level)) <= options.grey_tolerance;
            };
            for (auto v : vertices) {
                const MeshColor c = (*colors)[v];
                if (near_fill(c.red()) && near_fill(c.green()) && near_fill(c.blue()))
                    grey.push_back(to_eigen(mesh.point(v)));
            }
        }
        std::vector<char> near_samples, near_grey;
        if (options.far_tau_m == options.grey_tau_m && !samples.empty() && !grey.empty()) {
            const std::size_t n = samples.size();
            samples.insert(samples.end(), grey.begin(), grey.end());
            near_samples = within_distance(samples, *input_points, options.far_tau_m);
            near_grey.assign(near_samples.begin() + static_cast<std::ptrdiff_t>(n),
                             near_samples.end());
            near_samples.resize(n);
        } else {
            if (!samples.empty())
                near_samples = within_distance(samples, *input_points, options.far_tau_m);
            if (!grey.empty()) near_grey = within_distance(grey, *input_points, options.grey_tau_m);
        }
        if (total_area > 0.0) {
            std::size_t far = 0;
            for (char x : near_samples) far += x == 0;
            out[far_key] = double(far) / double(near_samples.size());
        } else {
            out[far_key] = nullptr;
        }
        if (colors && !vertices.empty()) {
            std::size_t observed = 0;
            for (char x : near_grey) observed += x != 0;
            out["grey_vertices"] = observed;
            out["grey_vertex_fraction"] = double(observed) / double(vertices.size());
        } else {
            out["grey_vertices"] = nullptr;
            out["grey_vertex_fraction"] = nullptr;
        }
        out["far_tau_m"] = options.far_tau_m;
        out["grey_tau_m"] = options.grey_tau_m;
    }
    if (options.self_intersections) out.update(reconstruction::self_intersection_counts(mesh));
    out["time_s"] = watch.seconds();
    return out;
}

}  // namespace rgbd::evaluation
