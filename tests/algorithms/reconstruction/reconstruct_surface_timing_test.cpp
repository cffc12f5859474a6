// Timings of the reconstruction on 30k and 60k sphere samples (label: slow).
#include <CGAL/boost/graph/helpers.h>
#include <gtest/gtest.h>

#include <iostream>

#include "algorithms/reconstruction/reconstruct_surface.hpp"
#include "sphere_cloud.hpp"

namespace {

void time_method(const char* method, int n) {
    const rgbd::PointCloud cloud = rgbd::test::coloured_sphere(n, 0.1);
    rgbd::reconstruction::ReconstructionOptions options;
    options.method = method;
    rgbd::Report report;
    const rgbd::Mesh mesh = rgbd::reconstruction::reconstruct_surface(cloud, options, &report);
    std::cout << method << " " << n << " points: " << report.dump() << "\n";
    ::testing::Test::RecordProperty(std::string(method) + "_" + std::to_string(n) + "_time_s",
                                    std::to_string(report["time_s"].get<double>()));
    EXPECT_GT(mesh.number_of_faces(), 0u);
    if (std::string(method) == "poisson") {
        EXPECT_TRUE(CGAL::is_closed(mesh));
    }
}

TEST(ReconstructSurfaceTiming, Front30k) { time_method("front", 30000); }
TEST(ReconstructSurfaceTiming, Front60k) { time_method("front", 60000); }
TEST(ReconstructSurfaceTiming, Poisson30k) { time_method("poisson", 30000); }
TEST(ReconstructSurfaceTiming, Poisson60k) { time_method("poisson", 60000); }
TEST(ReconstructSurfaceTiming, AdvancingFront30k) { time_method("advancing-front", 30000); }
TEST(ReconstructSurfaceTiming, AdvancingFront60k) { time_method("advancing-front", 60000); }

}  // namespace
