// libFuzzer target: the capture folder v1 reader (io/capture_folder.hpp). A valid one-sensor
// folder (8x6 images, two frames) is made once; the first input byte picks the file the rest
// replaces (rig.json, frames.csv, framesets.csv, the first depth PNG), then open_capture and
// load_frame of every frame read it, and the file is restored.
#include <algorithm>
#include <numeric>
#include <opencv2/core.hpp>
#include <vector>

#include "io/capture_folder.hpp"
#include "validation/robustness/fuzz/fuzz_support.hpp"

namespace {

namespace fs = std::filesystem;

struct Base {
    fs::path root;
    std::array<fs::path, 4> files;
    std::string original[4];
};

const Base& base() {
    static const Base b = [] {
        Base b;
        b.root = rgbd::fuzz::scratch() / "capture";
        fs::remove_all(b.root);
        b.files =
            rgbd::fuzz::write_small_capture(b.root, cv::Mat(6, 8, CV_32FC1, cv::Scalar(1.5f)));
        for (int i = 0; i < 4; ++i) b.original[i] = rgbd::fuzz::slurp(b.files[i]);
        return b;
    }();
    return b;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size < 1) return 0;
    const Base& b = base();
    const int role = data[0] % 4;
    rgbd::fuzz::write_file(b.files[role], data + 1, size - 1);
    rgbd::fuzz::open_and_load(b.root, [](std::size_t n) {  // the first four frames
        std::vector<std::size_t> first(std::min<std::size_t>(n, 4));
        std::iota(first.begin(), first.end(), std::size_t(0));
        return first;
    });
    rgbd::fuzz::write_file(b.files[role], b.original[role]);
    return 0;
}
