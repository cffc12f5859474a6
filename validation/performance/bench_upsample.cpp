// Benchmark of upsample_view (docs/algorithms.md §5): 8- and 4-neighbour super-resolution of one
// Kinect v2 view on one core. Frame: RGBD_UPSAMPLE_CAPTURE (a capture folder, sensor = first
// of rig.json, first frame), else a synthetic 512x424 frame with a sphere of 0.2 m radius at
// 1.5 m (about the point count of a bust view).
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "algorithms/frames/depth_to_cloud.hpp"
#include "algorithms/upsample/upsample_view.hpp"
#include "bench_frame.hpp"
#include "io/capture_folder.hpp"

using namespace rgbd;

namespace {

RgbdFrame load() {
    if (const char* cap = std::getenv("RGBD_UPSAMPLE_CAPTURE")) {
        const io::Capture capture = io::open_capture(cap);
        return io::load_frame(capture, capture.rig.sensors.front().id, 0);
    }
    return bench::synthetic_sphere_frame();
}

void run(benchmark::State& state, int neighbors) {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    const RgbdFrame frame = load();
    frames::CloudOptions copt;
    const PointCloud base = frames::depth_to_cloud(frame, copt);
    upsample::UpsampleOptions options;
    options.neighbors = neighbors;
    std::size_t points = 0;
    double prepare_s = 0, children_s = 0, append_s = 0;
    for (auto _ : state) {
        state.PauseTiming();
        PointCloud cloud = base;
        state.ResumeTiming();
        const Report report = upsample::upsample_view(cloud, frame, options);
        points = cloud.size();
        prepare_s += report["time_prepare_s"].get<double>();
        children_s += report["time_children_s"].get<double>();
        append_s += report["time_append_s"].get<double>();
        benchmark::DoNotOptimize(points);
    }
    state.counters["input_points"] = static_cast<double>(base.size());
    state.counters["output_points"] = static_cast<double>(points);
    // Timing splits (ms per iteration): point table, children, appending to the point set.
    const double iters =
        static_cast<double>(std::max<benchmark::IterationCount>(1, state.iterations()));
    state.counters["prepare_ms"] = 1e3 * prepare_s / iters;
    state.counters["children_ms"] = 1e3 * children_s / iters;
    state.counters["append_ms"] = 1e3 * append_s / iters;
}

void BM_UpsampleKinectV2View8(benchmark::State& state) { run(state, 8); }
void BM_UpsampleKinectV2View4(benchmark::State& state) { run(state, 4); }

}  // namespace

BENCHMARK(BM_UpsampleKinectV2View8)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_UpsampleKinectV2View4)->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
