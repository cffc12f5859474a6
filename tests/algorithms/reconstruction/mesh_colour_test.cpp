// The reconstructed mesh's vertex colours (internal::prepare_colours, colour_points and
// colorize, docs/algorithms.md §14): the inverse-distance-squared mean of a vertex's nearest
// points, observed points first, checked against brute force.
#include "algorithms/reconstruction/mesh_colour.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "algorithms/reconstruction/reconstruct_surface.hpp"
#include "sphere_cloud.hpp"

namespace {

using rgbd::Mesh;
using rgbd::PointCloud;
using rgbd::reconstruction::ReconstructionOptions;

constexpr double kRadius = 0.1;

// A vertex's colour is the inverse-distance-squared mean of its k nearest points: of the observed
// points alone (measured or super-resolved) when one lies within color_original_radius spacings,
// else of all points (the observed and the fill's, searched apart and merged). Checked against a
// brute-force search on a sphere whose colours vary from point to point, with a fill over its top
// and queries on and well off the surface.
TEST(ReconstructSurface, VertexColoursAreTheNearestPointsMean) {
    namespace internal = rgbd::reconstruction::internal;
    PointCloud cloud = rgbd::test::coloured_sphere(4000, kRadius);
    auto synthetic = cloud.add_flag(rgbd::prop::kSynthetic);
    auto colour_pixel = cloud.add_flag(rgbd::prop::kColourPixel);
    auto colors = cloud.colors();
    std::vector<Eigen::Vector3d> xyz;
    std::vector<rgbd::Rgb> rgb;
    std::vector<bool> observed;
    std::size_t i = 0;
    for (auto idx : cloud.points) {
        const Eigen::Vector3d p = rgbd::to_eigen(cloud.points.point(idx));
        const bool fill = p.z() > 0.6 * kRadius;  // the top is the fill's
        // Every fourth point of the rest is super-resolved: synthetic, but its colour observed.
        const bool super_resolved = !fill && i++ % 4 == 0;
        synthetic[idx] = fill || super_resolved ? 1 : 0;
        colour_pixel[idx] = super_resolved ? 1 : 0;
        const rgbd::Rgb c{static_cast<unsigned char>(128 + 1000 * p.x()),
                          static_cast<unsigned char>(128 + 1000 * p.y()),
                          static_cast<unsigned char>(fill ? 250 : 10)};
        colors.set(idx, c);
        xyz.push_back(p);
        rgb.push_back(c);
        observed.push_back(!fill);
    }
    internal::ColourSources sources;
    ASSERT_TRUE(internal::prepare_colours(cloud, sources));
    EXPECT_TRUE(sources.separate);
    const ReconstructionOptions o;
    const double spacing = 0.003;
    const double near = o.color_original_radius * spacing;
    const auto k = static_cast<std::size_t>(o.color_k);
    // Queries on the sphere and 30% outside it (a closure's vertices far from every point).
    std::vector<Eigen::Vector3d> queries;
    for (int i = 0; i < 600; ++i) {
        const double z = 1.0 - 2.0 * (i + 0.25) / 600, r = std::sqrt(1.0 - z * z);
        const Eigen::Vector3d u(r * std::cos(2.4 * i), r * std::sin(2.4 * i), z);
        queries.push_back((i % 3 == 0 ? 1.3 : 1.0) * kRadius * u);
    }
    const internal::KnownColours found = internal::colour_points(queries, sources, o, spacing);
    std::size_t fill_coloured = 0;
    for (const Eigen::Vector3d& q : queries) {
        std::vector<std::pair<double, std::size_t>> by_distance, observed_only;
        for (std::size_t i = 0; i < xyz.size(); ++i) {
            by_distance.emplace_back((xyz[i] - q).squaredNorm(), i);
            if (observed[i]) observed_only.push_back(by_distance.back());
        }
        std::sort(by_distance.begin(), by_distance.end());
        std::sort(observed_only.begin(), observed_only.end());
        const auto& nearest =
            std::sqrt(observed_only.front().first) <= near ? observed_only : by_distance;
        double w_sum = 0, rs = 0, gs = 0, bs = 0;
        for (std::size_t j = 0; j < k; ++j) {
            const double d = std::max(std::sqrt(nearest[j].first), 1e-3 * spacing);
            const double w = 1.0 / (d * d);
            const rgbd::Rgb& c = rgb[nearest[j].second];
            w_sum += w, rs += w * c.r, gs += w * c.g, bs += w * c.b;
        }
        const rgbd::MeshColor* c = found.find(q);
        ASSERT_NE(c, nullptr);
        const auto channel = [&](double s) { return long(std::lround(s / w_sum)); };
        EXPECT_EQ(long(c->r()), channel(rs));
        EXPECT_EQ(long(c->g()), channel(gs));
        EXPECT_EQ(long(c->b()), channel(bs));
        fill_coloured += c->b() > 100;
    }
    // The top's queries took the fill's colour (the merge reached the fill's points).
    EXPECT_GT(fill_coloured, 50u);
}

// Colours computed before the mesh, at the positions of its vertices, are the colours colorize
// finds; a vertex at a known position takes the known colour, the others are searched.
TEST(ReconstructSurface, KnownColoursAreTheColoursColorizeFinds) {
    namespace internal = rgbd::reconstruction::internal;
    const PointCloud cloud = rgbd::test::coloured_sphere(6000, kRadius, /*with_synthetic=*/true);
    const Mesh mesh = rgbd::reconstruction::reconstruct_surface(cloud, {});
    internal::ColourSources sources;
    ASSERT_TRUE(internal::prepare_colours(cloud, sources));
    const ReconstructionOptions o;
    const double spacing = 0.002;
    Mesh searched = mesh;
    internal::colorize(searched, sources, o, spacing);
    std::vector<Eigen::Vector3d> xyz;
    for (auto v : mesh.vertices()) xyz.push_back(rgbd::to_eigen(mesh.point(v)));
    // Every other vertex known: half looked up, half searched.
    std::vector<Eigen::Vector3d> half;
    for (std::size_t i = 0; i < xyz.size(); i += 2) half.push_back(xyz[i]);
    const internal::KnownColours known = internal::colour_points(half, sources, o, spacing);
    EXPECT_EQ(known.size(), half.size());
    Mesh looked_up = mesh;
    internal::colorize(looked_up, sources, o, spacing, &known);
    const auto cs = *rgbd::vertex_colors(searched), cl = *rgbd::vertex_colors(looked_up);
    for (auto v : mesh.vertices()) EXPECT_EQ(cl[v], cs[v]);
    // A known colour that the search would not give is taken as it is.
    internal::KnownColours marked;
    const auto first = *mesh.vertices().begin();
    marked.insert(rgbd::to_eigen(mesh.point(first)), rgbd::MeshColor(1, 2, 3));
    Mesh with_mark = mesh;
    internal::colorize(with_mark, sources, o, spacing, &marked);
    const auto cm = *rgbd::vertex_colors(with_mark);
    EXPECT_EQ(cm[first], rgbd::MeshColor(1, 2, 3));
    EXPECT_NE(cs[first], rgbd::MeshColor(1, 2, 3));
    for (auto v : mesh.vertices()) {
        if (v != first) {
            EXPECT_EQ(cm[v], cs[v]);
        }
    }
    EXPECT_EQ(marked.find(Eigen::Vector3d(9, 9, 9)), nullptr);
}

}  // namespace
