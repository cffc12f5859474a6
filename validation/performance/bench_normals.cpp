// Benchmark of estimate_normals (docs/algorithms.md §9) on one super-resolved Kinect v2 view,
// one core: the pixel-window neighbours of organised views against the kd-tree's kNN (issue 38:
// "normals of organised views from the pixel grid"). Frame: RGBD_NORMALS_CAPTURE (a capture
// folder, first sensor of rig.json, first frame), else a synthetic 512x424 frame with a sphere of
// 0.2 m radius at 1.5 m. RGBD_NORMALS_UPSAMPLE=0 keeps the measured points only (a point per
// pixel, as the person job's Kinect v1 views). Counter `same_share`: the share of normals within 1 deg of the
// kd-tree's.
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdlib>
#include <string>

#include "algorithms/frames/depth_to_cloud.hpp"
#include "algorithms/normals/estimate_normals.hpp"
#include "algorithms/upsample/upsample_view.hpp"
#include "bench_frame.hpp"
#include "io/capture_folder.hpp"

using namespace rgbd;

namespace {

/// The super-resolved view the alignment stage estimates normals on.
const PointCloud& view() {
    static const PointCloud cloud = [] {
        RgbdFrame frame;
        if (const char* cap = std::getenv("RGBD_NORMALS_CAPTURE")) {
            const io::Capture capture = io::open_capture(cap);
            frame = io::load_frame(capture, capture.rig.sensors.front().id, 0);
        } else {
            frame = bench::synthetic_sphere_frame();
        }
        PointCloud c = frames::depth_to_cloud(frame, frames::CloudOptions{});
        const char* up = std::getenv("RGBD_NORMALS_UPSAMPLE");
        if (!up || std::string(up) != "0") upsample::upsample_view(c, frame, {});
        return c;
    }();
    return cloud;
}

void run(benchmark::State& state, bool pixel_grid) {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    normals::NormalOptions options;
    options.pixel_grid = pixel_grid;
    PointCloud cloud = view();
    for (auto _ : state) {
        state.PauseTiming();
        cloud = view();
        state.ResumeTiming();
        benchmark::DoNotOptimize(normals::estimate_normals(cloud, options));
    }
    PointCloud reference = view();
    options.pixel_grid = false;
    normals::estimate_normals(reference, options);
    std::size_t same = 0;
    auto it = reference.points.begin();
    for (const auto idx : cloud.points)
        if (to_eigen(cloud.points.normal(idx)).dot(to_eigen(reference.points.normal(*it++))) >
            std::cos(1.0 * M_PI / 180.0))
            ++same;
    state.counters["points"] = static_cast<double>(cloud.size());
    state.counters["same_share"] = static_cast<double>(same) / cloud.size();
}

void BM_NormalsPixelWindow(benchmark::State& state) { run(state, true); }
void BM_NormalsKdTree(benchmark::State& state) { run(state, false); }

}  // namespace

BENCHMARK(BM_NormalsPixelWindow)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_NormalsKdTree)->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
