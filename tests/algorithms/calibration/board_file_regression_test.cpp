// Board files of `rgbd-calibrate --board` that the board reader (BoardSpec::from_json) got
// wrong, kept so they stay fixed (issue 21; validation/robustness/fuzz/fuzz_calibration_board
// searches for more): each must be refused with an InputError naming the key, never read as
// another board, and never reach undefined behaviour (the sanitizer build checks that).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
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
