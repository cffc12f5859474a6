// libFuzzer target: the foreign capture layouts read by io::open_capture. The first input byte
// picks the layout and file the rest replaces: TUM RGB-D (depth.txt, rgb.txt,
// groundtruth.txt) or Open3D/Redwood (the intrinsic JSON, the .log trajectory). Each layout's
// folder is made once, valid, with one frame, in memory (fuzz_support.hpp's scratch);
// open_capture reads it, and load_frame the first and the last frame it lists (the lists may
// name the one image thousands of times: reading it again tests nothing new and made this
// target 100 times slower). TUM's images are 640x480, the size its fixed intrinsics say;
// the Redwood folder's are 8x6, with a valid 8x6 intrinsic JSON beside the fuzzed trajectory.
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <vector>

#include "io/capture_folder.hpp"
#include "validation/robustness/fuzz/fuzz_support.hpp"

namespace {

namespace fs = std::filesystem;

/// The Redwood folder's camera: 8x6 pixels, f = 7 px, centred (Open3D's column-major matrix).
const char* const kRedwoodIntrinsics =
    R"({"width": 8, "height": 6, "intrinsic_matrix": [7, 0, 0, 0, 7, 0, 3.5, 2.5, 1]})";

struct Layout {
    fs::path tum, redwood;
};

/// Writes one frame into `folder`: a uniform depth image depth/<name>.png of `depth` units
/// and a uniform colour image <color_dir>/<name>.<color_ext>, both `width` x `height`.
void write_frame(const fs::path& folder, const std::string& color_dir, const std::string& name,
                 const std::string& color_ext, int width, int height, double depth) {
    fs::create_directories(folder / "depth");
    fs::create_directories(folder / color_dir);
    cv::imwrite((folder / "depth" / (name + ".png")).string(),
                cv::Mat(height, width, CV_16UC1, cv::Scalar(depth)));
    cv::imwrite((folder / color_dir / (name + color_ext)).string(),
                cv::Mat(height, width, CV_8UC3, cv::Scalar(50, 100, 150)));
}

const Layout& layout() {
    static const Layout l = [] {
        Layout l;
        l.tum = rgbd::fuzz::scratch() / "tum";
        l.redwood = rgbd::fuzz::scratch() / "redwood";
        fs::remove_all(l.tum);
        fs::remove_all(l.redwood);
        write_frame(l.tum, "rgb", "1.0", ".png", 640, 480, 5000);
        write_frame(l.redwood, "color", "000000", ".jpg", 8, 6, 1200);
        return l;
    }();
    return l;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size < 1) return 0;
    const Layout& l = layout();
    static const char* const kTum[] = {"depth.txt", "rgb.txt", "groundtruth.txt"};
    static const char* const kRedwood[] = {"camera_intrinsic.json", "trajectory.log"};
    const int role = data[0] % 5;
    const fs::path root = role < 3 ? l.tum : l.redwood;
    // The files the other roles would replace stay valid (or absent, also valid).
    rgbd::fuzz::write_file(l.tum / "depth.txt", "# depth\n1.0 depth/1.0.png\n");
    rgbd::fuzz::write_file(l.tum / "rgb.txt", "# rgb\n1.0 rgb/1.0.png\n");
    fs::remove(l.tum / "groundtruth.txt");
    rgbd::fuzz::write_file(l.redwood / kRedwood[0], kRedwoodIntrinsics);
    fs::remove(l.redwood / kRedwood[1]);
    const fs::path file = role < 3 ? l.tum / kTum[role] : l.redwood / kRedwood[role - 3];
    rgbd::fuzz::write_file(file, data + 1, size - 1);
    rgbd::fuzz::open_and_load(root, [](std::size_t n) {  // the first and the last frame
        if (n == 0) return std::vector<std::size_t>{};
        if (n == 1) return std::vector<std::size_t>{0};
        return std::vector<std::size_t>{0, n - 1};
    });
    return 0;
}
