// Times registration::align_pair (the pair ICP that rgbd-align runs) on two PLY clouds with
// normals for a fixed number of iterations at one correspondence distance, the way
// validation/performance/icp_vs_open3d.py times Open3D's point-to-plane ICP on the same files.
// Usage: icp_pair_timer SOURCE.ply TARGET.ply DISTANCE_M ITERATIONS REPEATS [THREADS]
// Prints one JSON line: median seconds, fitness, inlier RMSE, iterations run.
#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "algorithms/registration/icp.hpp"
#include "io/mesh_io.hpp"

int main(int argc, char** argv) {
    if (argc < 6) {
        std::fprintf(stderr,
                     "usage: icp_pair_timer SOURCE.ply TARGET.ply DISTANCE_M ITERATIONS REPEATS "
                     "[THREADS]\n");
        return 2;
    }
    try {
        const rgbd::PointCloud source = rgbd::io::read_point_cloud(argv[1]);
        const rgbd::PointCloud target = rgbd::io::read_point_cloud(argv[2]);
        const double distance = std::stod(argv[3]);
        const int iterations = std::stoi(argv[4]);
        const int repeats = std::max(1, std::stoi(argv[5]));
        std::unique_ptr<tbb::global_control> threads;
        if (argc > 6 && std::stoi(argv[6]) > 0)
            threads = std::make_unique<tbb::global_control>(
                tbb::global_control::max_allowed_parallelism, std::stoi(argv[6]));
        rgbd::registration::IcpOptions o;
        o.max_distances_m = {distance};
        o.criteria.max_iterations = iterations;
        o.criteria.relative_fitness = 0;  // run every iteration, as Open3D with 0 / 0
        o.criteria.relative_rmse = 0;
        o.criteria.min_rotation_deg = 0;
        o.criteria.min_translation_spacing = 0;
        std::vector<double> times;
        rgbd::registration::AlignResult r;
        for (int k = 0; k < repeats; ++k) {
            const auto t0 = std::chrono::steady_clock::now();
            r = rgbd::registration::align_pair(source, target, rgbd::Pose::Identity(), o);
            times.push_back(
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
        }
        std::sort(times.begin(), times.end());
        std::printf("{\"seconds\": %.6f, \"fitness\": %.6f, \"inlier_rmse\": %.6g, "
                    "\"iterations\": %d, \"points\": %zu}\n",
                    times[times.size() / 2], r.fitness, r.inlier_rmse, r.iterations, source.size());
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "icp_pair_timer: %s\n", e.what());
        return 1;
    }
}
