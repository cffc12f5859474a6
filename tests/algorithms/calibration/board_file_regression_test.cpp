// Board files of `rgbd-calibrate --board` that the board reader (BoardSpec::from_json) got
// wrong, kept so they stay fixed (issue 21; validation/robustness/fuzz/fuzz_calibration_board
// searches for more): each must be refused with an InputError naming the key, never read as
// another board, and never reach undefined behaviour (the sanitizer build checks that); a board
// it accepts draws (board_image) or is refused with an InputError, never an OpenCV exception.
#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>

#include "algorithms/calibration/charuco_board.hpp"
#include "toolkit/error.hpp"

namespace {

using rgbd::calibration::BoardSpec;

std::string refusal(const std::string& text) {
    try {
        BoardSpec::from_json(nlohmann::json::parse(text));
    } catch (const rgbd::InputError& e) {
        return e.what();
    }
    return "";
}

}  // namespace

TEST(BoardFileRegression, SquareCountsMustBeIntegersNotTruncatedWrappedOrOverflowed) {
    // get<int>() made 7 of each of the first three and was undefined for the fourth.
    for (const char* count : {"7.9", "4294967303", "-4294967289", "1e30", "-1e300", "true"}) {
        SCOPED_TRACE(count);
        const std::string err = refusal(std::string(R"({"squares_x": )") + count + "}");
        EXPECT_NE(err.find("squares_x"), std::string::npos) << err;
        EXPECT_TRUE(refusal(std::string(R"({"squares_y": )") + count + "}").find("squares_y") !=
                    std::string::npos);
    }
    const BoardSpec ok = BoardSpec::from_json(nlohmann::json::parse(R"({"squares_x": 9})"));
    EXPECT_EQ(ok.squares_x, 9);
}

TEST(BoardFileRegression, MarkersTooSmallToDrawAreAnInputErrorNotAnOpenCvException) {
    // fuzz_calibration_board (issue 39): this board is valid, but drawn 240 pixels on its long
    // side (as the target and rgbd-synth's printed boards do) its markers are 5.6 pixels wide,
    // under the 7 that OpenCV's drawMarker needs for DICT_5X5: its cv::Exception escaped
    // board_image and aborted the fuzzer.
    const BoardSpec board =
        BoardSpec::from_json(nlohmann::json::parse(R"({"squares_x": 6, "squares_y": 32})"));
    const double pixels_per_m = 240.0 / std::max(board.width_m(), board.height_m());
    try {
        rgbd::calibration::board_image(board, pixels_per_m);
        ADD_FAILURE() << "drew 5.6-pixel markers";
    } catch (const rgbd::InputError& e) {
        const std::string message = e.what();
        EXPECT_NE(message.find("6 x 32 board"), std::string::npos) << message;
        EXPECT_NE(message.find("too small to draw"), std::string::npos) << message;
    }
    // At twice the resolution the markers are 11 pixels wide and the board draws.
    const cv::Mat image = rgbd::calibration::board_image(board, 2 * pixels_per_m);
    EXPECT_EQ(image.type(), CV_8UC1);
    EXPECT_EQ(image.rows, 480);
}

TEST(BoardFileRegression, EveryAcceptedBoardDrawsOrIsRefusedWithAnInputError) {
    // The fuzz target's contract over the whole range of square counts and each dictionary
    // size: at the target's 240 pixels no OpenCV exception escapes board_image.
    for (const char* dictionary : {"DICT_4X4_1000", "DICT_7X7_1000", "DICT_ARUCO_ORIGINAL"})
        for (int sx = 2; sx <= 40; sx += 3)
            for (int sy = 2; sy <= 40; sy += 5) {
                BoardSpec board;
                board.squares_x = sx;
                board.squares_y = sy;
                board.dictionary = dictionary;
                const double ppm = 240.0 / std::max(board.width_m(), board.height_m());
                try {
                    rgbd::calibration::board_image(board, ppm);
                } catch (const rgbd::InputError&) {
                }
            }
}
