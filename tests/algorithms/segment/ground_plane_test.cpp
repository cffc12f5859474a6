// detail::pooled_bounding_plane (algorithms/segment/ground_plane.hpp), the RANSAC behind the
// wall search: a sample votes for a plane only when it lies within half a band of it AND faces
// it. A thin slab of points whose normals lie along the slab (a slice through a body, not a
// surface) outnumbers a real plane of points facing it; the real plane must win, with exactly
// its points as inliers.
#include "algorithms/segment/ground_plane.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "algorithms/internal/plane_fit.hpp"

namespace {

using rgbd::segment::detail::GroundSample;

TEST(PooledBoundingPlane, VotesNeedTheSamplesToFaceThePlane) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0), up(0.1, 1.0), thin(-0.01, 0.01);
    std::vector<GroundSample> samples;
    // The plane z = 0, its points facing it (normal +z): 2000.
    for (int i = 0; i < 2000; ++i)
        samples.push_back({Eigen::Vector3d(u(rng), u(rng), 0.0), Eigen::Vector3d::UnitZ()});
    // A slab 2 cm thick about x = 0 above it, 4001 points (an odd count: the vector loop's
    // scalar tail runs too), normals along +z: within the band of x = 0 but facing away.
    for (int i = 0; i < 4001; ++i)
        samples.push_back({Eigen::Vector3d(thin(rng), u(rng), up(rng)), Eigen::Vector3d::UnitZ()});
    std::vector<std::uint8_t> used(samples.size(), 0);
    rgbd::segment::SubjectOptions options;
    std::size_t inliers = 0, behind = 0;
    const auto plane = rgbd::segment::detail::pooled_bounding_plane(
        samples, used, Eigen::Vector3d(0.5, 0.3, 2.0), options, 11, inliers, behind);
    ASSERT_TRUE(plane.has_value());
    EXPECT_GT(plane->n.z(), std::cos(1.0 * M_PI / 180.0)) << plane->n.transpose();
    EXPECT_LT(std::abs(plane->d), 1e-9);
    EXPECT_EQ(inliers, 2000u);
    for (std::size_t i = 0; i < samples.size(); ++i) EXPECT_EQ(used[i], i < 2000 ? 1 : 0) << i;
}

// internal::count_plane_votes counts 4 (AVX2) or 2 (SSE2) points at a time: the same count as
// the scalar test |n . p + d| <= band (and |n . normal| >= cos_tilt) with Eigen's dot, for every
// remainder of the vector loop, with points exactly on the band's edge and NaN coordinates.
TEST(PlaneVotes, TheVectorCountIsTheScalarCount) {
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (std::size_t m : {0u, 1u, 2u, 3u, 5u, 6u, 7u, 1000u, 1003u}) {
        std::vector<Eigen::Vector3d> p(m), nrm(m);
        for (std::size_t i = 0; i < m; ++i) {
            p[i] = Eigen::Vector3d(u(rng), u(rng), 0.05 * u(rng));
            nrm[i] = Eigen::Vector3d(0.3 * u(rng), 0.3 * u(rng), 1.0).normalized();
        }
        const Eigen::Vector3d n = Eigen::Vector3d(0.02, -0.01, 1.0).normalized();
        const double d = 0.001, band = 0.02;
        if (m > 3) {
            p[1].z() = (band - d - n.x() * p[1].x() - n.y() * p[1].y()) / n.z();  // near the edge
            p[2].x() = std::nan("");
        }
        std::vector<double> soa(6 * m);
        for (std::size_t i = 0; i < m; ++i)
            for (int k = 0; k < 3; ++k) soa[k * m + i] = p[i][k], soa[(3 + k) * m + i] = nrm[i][k];
        rgbd::internal::PlaneVoteInput in;
        in.px = soa.data(), in.py = in.px + m, in.pz = in.py + m, in.m = m;
        std::size_t near = 0, facing = 0;
        const double cos_tilt = std::cos(10.0 * M_PI / 180.0);
        for (std::size_t i = 0; i < m; ++i) {
            const bool within = std::abs(n.dot(p[i]) + d) <= band;
            near += within;
            facing += within && std::abs(n.dot(nrm[i])) >= cos_tilt;
        }
        EXPECT_EQ(rgbd::internal::count_plane_votes(in, n, d, band, -1.0), near) << m;
        in.nx = in.pz + m, in.ny = in.nx + m, in.nz = in.ny + m;
        EXPECT_EQ(rgbd::internal::count_plane_votes(in, n, d, band, cos_tilt), facing) << m;
        if (m == 1000) {
            EXPECT_GT(near, 100u);
            EXPECT_LT(facing, near);
        }
    }
}

// A wall 1 m in front of a sensor (2 mm noise) with a book standing against it, its face 18 mm
// in front of the wall and 30% of the view's points. The view's refit lies on the wall, not
// between wall and book (the mode of the heights, not their mean), its noise is the wall's
// (measured behind the wall, where the book is not), and the cut takes the wall and keeps the
// book's face. A least-squares plane and a two-sided deviation (before) put the plane 4 mm
// forward and the noise at 7 mm, and the cut took a fifth of the book.
TEST(RefitViewGround, ABookAgainstAWallKeepsItsFaceAndTheWallGoes) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-0.3, 0.3);
    std::normal_distribution<double> noise(0.0, 0.002);
    std::vector<Eigen::Vector3d> xyz;
    std::vector<bool> book;
    while (xyz.size() < 30000) {
        const double x = u(rng), y = u(rng);
        const bool on_book = x > 0.0 && x < 0.2 && std::abs(y) < 0.2;
        // The book hides the wall behind it; it holds about 30% of the points.
        const double z = on_book ? 1.0 - 0.018 : 1.0;
        xyz.emplace_back(x * z, y * z, z + noise(rng));
        book.push_back(on_book);
    }
    // The pooled plane (facing the sensor: heights grow towards it), 1 cm off as a pose may be.
    const rgbd::segment::detail::Plane pooled{Eigen::Vector3d(0, 0, -1), 1.01};
    rgbd::segment::SubjectOptions options;
    const auto model = rgbd::denoise::NoiseModel::kKinectV2;
    const auto fit =
        rgbd::segment::detail::refit_view_ground(xyz, pooled, {}, model, options, 5, true);
    ASSERT_GT(fit.rms_m, 0.0);
    EXPECT_LT(fit.plane.n.z(), -std::cos(1.0 * M_PI / 180.0)) << fit.plane.n.transpose();
    EXPECT_NEAR(-fit.plane.d / fit.plane.n.z(), 1.0, 0.001) << fit.plane.n.transpose();
    EXPECT_LT(fit.rms_m, 0.0025);
    std::vector<std::uint8_t> removed(xyz.size(), 0);
    rgbd::segment::detail::cut_above_ground(xyz, fit, model, options, removed);
    std::size_t books = 0, books_kept = 0, walls = 0, walls_removed = 0;
    for (std::size_t i = 0; i < xyz.size(); ++i) {
        (book[i] ? books : walls) += 1;
        (book[i] ? books_kept : walls_removed) += book[i] ? !removed[i] : removed[i];
    }
    EXPECT_GE(static_cast<double>(books_kept) / books, 0.95);
    EXPECT_GE(static_cast<double>(walls_removed) / walls, 0.99);
}

}  // namespace
