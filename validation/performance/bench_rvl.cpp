// Benchmark of the RVL depth codec (io/rvl.hpp) on recorded depth against the baseline the
// capture folder uses, PNG (OpenCV, zlib level 1 and the default 3): compression ratio
// (raw 16-bit bytes / compressed bytes) and encode / decode time per frame, printed as ratios
// to PNG. Frames: every depth image of the capture folder given as the first argument (e.g. an
// rgbd-synth 8-Kinect ring capture); Google Benchmark flags follow.
//   bench_rvl CAPTURE_DIR [--benchmark_...]
#include <benchmark/benchmark.h>

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "io/capture_folder.hpp"
#include "io/rvl.hpp"

using namespace rgbd;

namespace {

std::vector<cv::Mat> g_frames;

void BM_RvlEncode(benchmark::State& state) {
    std::vector<std::uint8_t> out;
    std::size_t raw = 0, packed = 0, i = 0;
    for (auto _ : state) {
        const cv::Mat& d = g_frames[i++ % g_frames.size()];
        packed += io::rvl_compress(d.ptr<std::uint16_t>(), d.total(), out);
        raw += d.total() * 2;
        benchmark::DoNotOptimize(out.data());
    }
    state.counters["ratio"] = static_cast<double>(raw) / static_cast<double>(packed);
}

void BM_RvlDecode(benchmark::State& state) {
    std::vector<std::vector<std::uint8_t>> packed(g_frames.size());
    for (std::size_t k = 0; k < g_frames.size(); ++k)
        io::rvl_compress(g_frames[k].ptr<std::uint16_t>(), g_frames[k].total(), packed[k]);
    cv::Mat out(g_frames[0].size(), CV_16UC1);
    std::size_t i = 0;
    for (auto _ : state) {
        const std::size_t k = i++ % g_frames.size();
        io::rvl_decompress(packed[k].data(), packed[k].size(), out.ptr<std::uint16_t>(),
                           out.total());
        benchmark::DoNotOptimize(out.data);
    }
}

void BM_PngEncode(benchmark::State& state) {
    std::vector<std::uint8_t> out;
    const std::vector<int> params = {cv::IMWRITE_PNG_COMPRESSION, static_cast<int>(state.range(0))};
    std::size_t raw = 0, packed = 0, i = 0;
    for (auto _ : state) {
        const cv::Mat& d = g_frames[i++ % g_frames.size()];
        cv::imencode(".png", d, out, params);
        packed += out.size();
        raw += d.total() * 2;
    }
    state.counters["ratio"] = static_cast<double>(raw) / static_cast<double>(packed);
}

BENCHMARK(BM_RvlEncode)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RvlDecode)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_PngEncode)->Arg(1)->Arg(3)->Unit(benchmark::kMillisecond);

/// Collects per-benchmark time and ratio to print the comparison at the end.
class Collector : public benchmark::ConsoleReporter {
public:
    void ReportRuns(const std::vector<Run>& runs) override {
        for (const Run& r : runs) {
            times_ms[r.benchmark_name()] = r.GetAdjustedCPUTime();  // CPU: robust to load
            const auto it = r.counters.find("ratio");
            if (it != r.counters.end()) ratios[r.benchmark_name()] = it->second.value;
        }
        ConsoleReporter::ReportRuns(runs);
    }
    std::map<std::string, double> times_ms, ratios;
};

}  // namespace

int main(int argc, char** argv) {
    if (argc < 2 || std::string(argv[1]).rfind("--", 0) == 0) {
        std::cerr << "usage: bench_rvl CAPTURE_DIR [--benchmark_...]\n";
        return 2;
    }
    const io::Capture cap = io::open_capture(argv[1]);
    for (const auto& [id, frames] : cap.frames)
        for (const auto& f : frames) {
            const std::filesystem::path file = std::filesystem::path(f.depth).is_absolute()
                                                   ? std::filesystem::path(f.depth)
                                                   : cap.root / id / f.depth;
            const cv::Mat d = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
            if (d.type() != CV_16UC1) {
                std::cerr << "bench_rvl: " << file.string() << ": not a 16-bit depth image\n";
                return 1;
            }
            g_frames.push_back(d);
        }
    if (g_frames.empty()) {
        std::cerr << "bench_rvl: " << argv[1] << ": no depth frames\n";
        return 1;
    }
    argv[1] = argv[0];
    int n = argc - 1;
    benchmark::Initialize(&n, argv + 1);
    Collector collector;
    benchmark::RunSpecifiedBenchmarks(&collector);
    const double rvl_ms = collector.times_ms["BM_RvlEncode"];
    const double png1_ms = collector.times_ms["BM_PngEncode/1"];
    std::printf(
        "\nRVL on %zu depth frames (%dx%d) of %s: ratio %.2f (PNG level 1: %.2f, level 3: "
        "%.2f); encode %.3f ms/frame (CPU) = %.2fx PNG level 1's time; decode %.3f ms/frame\n",
        g_frames.size(), g_frames[0].cols, g_frames[0].rows, cap.root.c_str(),
        collector.ratios["BM_RvlEncode"], collector.ratios["BM_PngEncode/1"],
        collector.ratios["BM_PngEncode/3"], rvl_ms, png1_ms > 0 ? rvl_ms / png1_ms : 0.0,
        collector.times_ms["BM_RvlDecode"]);
    return 0;
}
