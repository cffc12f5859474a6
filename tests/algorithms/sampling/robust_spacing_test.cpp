#include "algorithms/sampling/robust_spacing.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <random>

#include "toolkit/error.hpp"

namespace {

rgbd::PointSet grid(int nx, int ny, double step) {
    rgbd::PointSet points;
    for (int y = 0; y < ny; ++y)
        for (int x = 0; x < nx; ++x) points.insert(rgbd::Point_3(x * step, y * step, 0.3));
    return points;
}

TEST(RobustSpacing, RegularGridGivesItsStep) {
    const rgbd::PointSet points = grid(120, 100, 0.002);
    EXPECT_NEAR(rgbd::sampling::robust_spacing(points), 0.002, 1e-12);
    EXPECT_NEAR(rgbd::sampling::robust_spacing(points, 500, 7), 0.002, 1e-12);
}

TEST(RobustSpacing, RobustToOutliersAndDuplicatesMinority) {
    rgbd::PointSet points = grid(100, 100, 0.004);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-5, 5);
    for (int i = 0; i < 500; ++i) points.insert(rgbd::Point_3(u(rng), u(rng), u(rng)));
    for (int i = 0; i < 500; ++i) points.insert(rgbd::Point_3(i * 0.004, 0.0, 0.3));  // dups
    EXPECT_NEAR(rgbd::sampling::robust_spacing(points), 0.004, 1e-12);
}

TEST(RobustSpacing, SameResultForAnyThreadCountAndSeed) {
    rgbd::PointSet points;
    std::mt19937 rng(5);
    std::normal_distribution<double> n(0, 0.1);
    for (int i = 0; i < 30000; ++i) points.insert(rgbd::Point_3(n(rng), n(rng), n(rng)));
    double one, two;
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
        one = rgbd::sampling::robust_spacing(points, 10000, 42);
    }
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
        two = rgbd::sampling::robust_spacing(points, 10000, 42);
    }
    EXPECT_EQ(one, two);
    EXPECT_GT(one, 0.0);
}

TEST(RobustSpacing, RejectsTooFewPoints) {
    rgbd::PointSet points;
    EXPECT_THROW(rgbd::sampling::robust_spacing(points), rgbd::InputError);
    points.insert(rgbd::Point_3(0, 0, 0));
    EXPECT_THROW(rgbd::sampling::robust_spacing(points), rgbd::InputError);
    points.insert(rgbd::Point_3(0, 0, 0.01));
    EXPECT_NEAR(rgbd::sampling::robust_spacing(points), 0.01, 1e-12);
}

}  // namespace
