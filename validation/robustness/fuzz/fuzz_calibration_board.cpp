// libFuzzer target: the ChArUco board file of `rgbd-calibrate --board FILE.json`
// (algorithms/calibration/charuco_board.hpp: BoardSpec::from_json behind the tool's JSON
// parse). The input is the file's bytes. A board the reader accepts must then be usable the
// way rgbd-calibrate uses it: its printable image (at about 240 pixels on the long side), the
// position of every inner corner, and a detection run (OpenCV's CharucoBoard of the spec).
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "algorithms/calibration/charuco_board.hpp"
#include "validation/robustness/fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    nlohmann::json json;
    try {  // rgbd-calibrate reports a JSON syntax error as "not a JSON board description"
        json = nlohmann::json::parse(data, data + size);
    } catch (const nlohmann::json::exception&) {
        return 0;
    }
    rgbd::fuzz::expect_clean([&] {
        const rgbd::calibration::BoardSpec board = rgbd::calibration::BoardSpec::from_json(json);
        const double pixels_per_m = 240.0 / std::max(board.width_m(), board.height_m());
        const cv::Mat image = rgbd::calibration::board_image(board, pixels_per_m);
        if (image.empty() || image.type() != CV_8UC1) __builtin_trap();
        for (int id = 0; id < board.corner_count(); ++id) {
            const Eigen::Vector3d c = board.corner(id);
            if (!(c.x() > 0 && c.x() < board.width_m() && c.y() > 0 && c.y() < board.height_m()))
                __builtin_trap();  // an inner corner outside the board
        }
        rgbd::PinholeIntrinsics k;
        k.width = image.cols;
        k.height = image.rows;
        k.fx = k.fy = 100;
        k.cx = 0.5 * (image.cols - 1);
        k.cy = 0.5 * (image.rows - 1);
        rgbd::calibration::detect_board(image, k, board);
    });
    return 0;
}
