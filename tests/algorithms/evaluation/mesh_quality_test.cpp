// Tests of the mesh cleanliness measure with known answers: a regular icosphere (no slivers,
// folds or spikes), a flat grid with a needle, a 7-degree sliver and a folded flap (exact
// fractions), a plane offset 5 mm / 1 mm from its input points (far area 1 / 0), grey fill
// vertices near and far from the points, two crossing spheres (self-intersections), options
// checks and thread-count determinism.
#include "algorithms/evaluation/mesh_quality.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <array>
#include <cmath>
#include <map>
#include <numbers>

#include "tests/validation/synth_test_shapes.hpp"
#include "toolkit/error.hpp"

namespace rgbd::evaluation {
namespace {

constexpr double kPi = std::numbers::pi;
using synth::testing::icosphere;

/// Adds a triangle (three new vertices) to `mesh`.
void add_triangle(Mesh& mesh, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                  const Eigen::Vector3d& c) {
    mesh.add_face(mesh.add_vertex(to_point(a)), mesh.add_vertex(to_point(b)),
                  mesh.add_vertex(to_point(c)));
}

/// Flat n x n grid of squares of side `step` at height z, each square split into two triangles
/// ((n+1)^2 vertices, 2 n^2 faces, 3 n^2 - 2 n interior edges).
Mesh grid(int n, double step, double z = 0.0) {
    Mesh mesh;
    std::vector<Mesh::Vertex_index> ids;
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) ids.push_back(mesh.add_vertex(Point_3(i * step, j * step, z)));
    auto at = [&](int i, int j) { return ids[std::size_t(j * (n + 1) + i)]; };
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            mesh.add_face(at(i, j), at(i + 1, j), at(i + 1, j + 1));
            mesh.add_face(at(i, j), at(i + 1, j + 1), at(i, j + 1));
        }
    return mesh;
}

/// Points on a regular grid of spacing `step` covering [lo, hi]^2 at height z.
std::vector<Eigen::Vector3d> point_grid(double lo, double hi, double step, double z) {
    std::vector<Eigen::Vector3d> p;
    const int n = int(std::lround((hi - lo) / step));
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) p.emplace_back(lo + i * step, lo + j * step, z);
    return p;
}

TEST(MeshQuality, RegularIcosphereIsClean) {
    for (int levels : {0, 2, 4}) {
        const Mesh mesh = icosphere(0.1, levels);
        const Report r = mesh_quality(mesh, nullptr);
        EXPECT_EQ(r["faces"].get<std::size_t>(), 20u << (2 * levels));
        EXPECT_EQ(r["sliver_fraction_5deg"].get<double>(), 0.0);
        EXPECT_EQ(r["sliver_fraction_10deg"].get<double>(), 0.0);
        EXPECT_EQ(r["sliver_area_fraction_5deg"].get<double>(), 0.0);
        EXPECT_EQ(r["fold_edge_fraction"].get<double>(), 0.0);
        EXPECT_EQ(r["spike_vertex_fraction"].get<double>(), 0.0);
        EXPECT_EQ(r["edges_interior"].get<std::size_t>(), 30u << (2 * levels));
        EXPECT_FALSE(r.contains("far_area_fraction_3mm"));
        EXPECT_FALSE(r.contains("grey_vertex_fraction"));
        EXPECT_EQ(r["self_intersecting_pairs"], 0);
        EXPECT_EQ(r["self_intersecting_faces"], 0);
    }
}

TEST(MeshQuality, CountsTheFacesOfTwoCrossingSpheres) {
    Mesh mesh;
    synth::testing::add_icosphere(mesh, Eigen::Vector3d::Zero(), 0.1, 2);
    synth::testing::add_icosphere(mesh, Eigen::Vector3d(0.1, 0.0, 0.0), 0.1, 2);
    const Report r = mesh_quality(mesh, nullptr);
    EXPECT_GT(r["self_intersecting_pairs"].get<std::size_t>(), 10u);
    EXPECT_GT(r["self_intersecting_faces"].get<std::size_t>(), 10u);
    MeshQualityOptions no_count;
    no_count.self_intersections = false;
    EXPECT_FALSE(mesh_quality(mesh, nullptr, no_count).contains("self_intersecting_pairs"));
}

TEST(MeshQuality, NeedleSliverAndFlapGiveExactFractions) {
    Mesh mesh = grid(2, 1.0);  // 9 vertices, 8 right isosceles faces, 8 interior edges
    // Needle: minimum angle atan(0.01 / 0.5) = 1.15 deg, area 0.005.
    add_triangle(mesh, {5, 0, 0}, {6, 0, 0}, {5.5, 0.01, 0});
    // Sliver of 7 deg (both base angles), area 0.25 tan 7 deg.
    const double h7 = 0.5 * std::tan(7.0 * kPi / 180.0);
    add_triangle(mesh, {8, 0, 0}, {9, 0, 0}, {8.5, h7, 0});
    // Flap: t1 (normal +z, area 0.5) and t2 folded back over it across the edge b-c:
    // t2's normal is (-0.1, -0.1, -0.6) / |.|, 166.8 deg from t1's, area sqrt(0.38) / 2.
    const Eigen::Vector3d o(20, 0, 0);
    const auto a = mesh.add_vertex(to_point(o));
    const auto b = mesh.add_vertex(to_point(o + Eigen::Vector3d(1, 0, 0)));
    const auto c = mesh.add_vertex(to_point(o + Eigen::Vector3d(0, 1, 0)));
    const auto d = mesh.add_vertex(to_point(o + Eigen::Vector3d(0.2, 0.2, 0.1)));
    ASSERT_NE(mesh.add_face(a, b, c), Mesh::null_face());
    ASSERT_NE(mesh.add_face(c, b, d), Mesh::null_face());

    const Report r = mesh_quality(mesh, nullptr);
    EXPECT_EQ(r["faces"].get<std::size_t>(), 12u);
    EXPECT_DOUBLE_EQ(r["sliver_fraction_5deg"].get<double>(), 1.0 / 12.0);
    EXPECT_DOUBLE_EQ(r["sliver_fraction_10deg"].get<double>(), 2.0 / 12.0);
    const double total =
        4.0 + 0.005 + 0.25 * std::tan(7.0 * kPi / 180.0) + 0.5 + 0.5 * std::sqrt(0.38);
    EXPECT_NEAR(r["area_m2"].get<double>(), total, 1e-12);
    EXPECT_NEAR(r["sliver_area_fraction_5deg"].get<double>(), 0.005 / total, 1e-12);
    EXPECT_NEAR(r["sliver_area_fraction_10deg"].get<double>(),
                (0.005 + 0.25 * std::tan(7.0 * kPi / 180.0)) / total, 1e-12);
    // Interior edges: 8 of the grid + the flap's hinge, which is the only fold.
    EXPECT_EQ(r["edges_interior"].get<std::size_t>(), 9u);
    EXPECT_EQ(r["fold_edges"].get<std::size_t>(), 1u);
    EXPECT_DOUBLE_EQ(r["fold_edge_fraction"].get<double>(), 1.0 / 9.0);
    // Spikes: the hinge's two vertices b and c (t2 deviates 147 deg from their normal);
    // a and d have one face each. 9 + 3 + 3 + 4 vertices.
    EXPECT_EQ(r["spike_vertices"].get<std::size_t>(), 2u);
    EXPECT_DOUBLE_EQ(r["spike_vertex_fraction"].get<double>(), 2.0 / 19.0);
}

TEST(MeshQuality, SpikeOutOfAPlaneIsCaught) {
    // A vertex of a flat grid pulled 10 steps out: a thin cone. The tip and its ring are spikes.
    Mesh mesh = grid(4, 1.0);
    Mesh::Vertex_index centre;
    for (auto v : mesh.vertices())
        if (mesh.point(v) == Point_3(2, 2, 0)) centre = v;
    mesh.point(centre) = Point_3(2, 2, 10);
    const Report r = mesh_quality(mesh, nullptr);
    EXPECT_GT(r["spike_vertices"].get<std::size_t>(), 0u);
    EXPECT_EQ(r["fold_edges"].get<std::size_t>(), 0u);  // no edge folds back more than 120 deg
    const Report flat = mesh_quality(grid(4, 1.0), nullptr);
    EXPECT_EQ(flat["spike_vertices"].get<std::size_t>(), 0u);
}

TEST(MeshQuality, FarAreaOfOffsetPlane) {
    const Mesh mesh = grid(10, 0.01);  // 0.1 m square at z = 0
    MeshQualityOptions options;
    options.samples = 20000;
    const auto far = point_grid(-0.01, 0.11, 0.001, 0.005);  // 5 mm above
    const Report r5 = mesh_quality(mesh, &far, options);
    EXPECT_EQ(r5["far_area_fraction_3mm"].get<double>(), 1.0);
    const auto near = point_grid(-0.01, 0.11, 0.001, 0.001);  // 1 mm above
    const Report r1 = mesh_quality(mesh, &near, options);
    EXPECT_EQ(r1["far_area_fraction_3mm"].get<double>(), 0.0);
    // Half the points removed (x > 0.05 only): about half the area is far.
    std::vector<Eigen::Vector3d> half;
    for (const auto& p : near)
        if (p.x() > 0.0535) half.push_back(p);
    const Report rh = mesh_quality(mesh, &half, options);
    EXPECT_NEAR(rh["far_area_fraction_3mm"].get<double>(), 0.5, 0.02);
    // No colours: grey fraction unknown.
    EXPECT_TRUE(r1["grey_vertex_fraction"].is_null());
}

TEST(MeshQuality, GreyVerticesCountOnlyNearObservedPoints) {
    Mesh mesh = grid(2, 0.01);                        // 9 vertices, spacing 1 cm
    VertexColorMap colors = add_vertex_colors(mesh);  // all (128, 128, 128)
    int k = 0;
    for (auto v : mesh.vertices())
        if (k++ >= 3) colors[v] = MeshColor(200, 120, 90);  // 3 grey vertices: row y = 0
    // Points 1 mm above x <= 0.005: vertices (0,0) grey & near, (0.01,0)/(0.02,0) grey & far.
    std::vector<Eigen::Vector3d> points = point_grid(-0.002, 0.005, 0.001, 0.001);
    const Report r = mesh_quality(mesh, &points, {});
    EXPECT_EQ(r["grey_vertices"].get<std::size_t>(), 1u);
    EXPECT_DOUBLE_EQ(r["grey_vertex_fraction"].get<double>(), 1.0 / 9.0);
    MeshQualityOptions tolerant;
    tolerant.grey_tolerance = 80;  // now every vertex is "grey", but only (0, 0) is observed
    EXPECT_EQ(mesh_quality(mesh, &points, tolerant)["grey_vertices"].get<std::size_t>(), 1u);
}

TEST(MeshQuality, RejectsBadInput) {
    EXPECT_THROW(mesh_quality(Mesh(), nullptr), InputError);
    const Mesh mesh = icosphere(0.1, 1);
    std::vector<Eigen::Vector3d> empty;
    EXPECT_THROW(mesh_quality(mesh, &empty), InputError);
    MeshQualityOptions bad;
    bad.fold_angle_deg = 180.0;
    EXPECT_THROW(mesh_quality(mesh, nullptr, bad), InputError);
    bad = {};
    bad.sliver_angles_deg.clear();
    EXPECT_THROW(mesh_quality(mesh, nullptr, bad), InputError);
    bad = {};
    bad.samples = 0;
    EXPECT_THROW(mesh_quality(mesh, nullptr, bad), InputError);
    std::vector<Eigen::Vector3d> nan{{std::nan(""), 0, 0}};
    EXPECT_THROW(mesh_quality(mesh, &nan), InputError);
}

TEST(MeshQuality, SameResultForAnyThreadCount) {
    const Mesh mesh = icosphere(0.1, 3);
    std::vector<Eigen::Vector3d> points;
    const Mesh dense = icosphere(0.1015, 4);
    for (auto v : dense.vertices()) points.push_back(to_eigen(dense.point(v)));
    Report one, many;
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
        one = mesh_quality(mesh, &points);
    }
    many = mesh_quality(mesh, &points);
    one.erase("time_s");
    many.erase("time_s");
    EXPECT_EQ(one, many);
}

}  // namespace
}  // namespace rgbd::evaluation
