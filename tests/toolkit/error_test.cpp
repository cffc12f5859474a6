// check_range, the range check of options fields: which values it lets through at closed and
// open ends, that NaN and infinities never pass, and the message it throws.
#include "toolkit/error.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>

#include "tests/support/input_error.hpp"

namespace rgbd {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

TEST(CheckRange, ClosedEndsBelongToTheRange) {
    const Range r = Range::closed(0, 1000);
    EXPECT_TRUE(r.contains(0.0));
    EXPECT_TRUE(r.contains(1000.0));
    EXPECT_TRUE(r.contains(0.5));
    EXPECT_FALSE(r.contains(-1e-300));
    EXPECT_FALSE(r.contains(std::nextafter(1000.0, kInf)));
    EXPECT_NO_THROW(check_range("alpha", 1000.0, r));
    EXPECT_THROW(check_range("alpha", 1000.5, r), InputError);
}

TEST(CheckRange, OpenEndsDoNot) {
    EXPECT_FALSE(Range::open_closed(0, 89).contains(0.0));
    EXPECT_TRUE(Range::open_closed(0, 89).contains(89.0));
    EXPECT_TRUE(Range::closed_open(0, 60).contains(0.0));
    EXPECT_FALSE(Range::closed_open(0, 60).contains(60.0));
    EXPECT_FALSE(Range::open(-80, 80).contains(-80.0));
    EXPECT_FALSE(Range::open(-80, 80).contains(80.0));
    EXPECT_TRUE(Range::open(-80, 80).contains(-79.999));
    EXPECT_THROW(check_range("theta_max", 0.0, Range::open_closed(0, 89)), InputError);
    EXPECT_NO_THROW(check_range("theta_max", 1e-9, Range::open_closed(0, 89)));
}

TEST(CheckRange, NaNAndInfinitiesNeverPass) {
    for (const double bad : {kNaN, kInf, -kInf}) {
        EXPECT_FALSE(Range::closed(-1e308, 1e308).contains(bad)) << bad;
        EXPECT_THROW(check_range("x", bad, Range::closed(0, 1)), InputError) << bad;
    }
    test::expect_input_error([] { check_range("beta", kNaN, Range::closed(0, 100)); },
                             {"beta must be in [0, 100], got nan"});
    test::expect_input_error([] { check_range("beta", -kInf, Range::closed(0, 100)); },
                             {"got -inf"});
}

TEST(CheckRange, MessageNamesTheFieldTheRangeTheUnitAndTheValue) {
    auto message = [](auto call) { return test::input_error_message(call); };
    EXPECT_EQ(
        message([] { check_range("distance outliers: alpha", 1500.0, Range::closed(0, 1000)); }),
        "distance outliers: alpha must be in [0, 1000], got 1500");
    EXPECT_EQ(message([] {
                  check_range("distance outliers: theta_max", 95.5, Range::open_closed(0, 89),
                              "degrees");
              }),
              "distance outliers: theta_max must be in (0, 89] degrees, got 95.5");
    EXPECT_EQ(message([] { check_range("stand: margin", -0.25, Range::closed_open(0, 1), "m"); }),
              "stand: margin must be in [0, 1) m, got -0.25");
    EXPECT_EQ(message([] { check_range("tilt", 80.0, Range::open(-80, 80), "deg"); }),
              "tilt must be in (-80, 80) deg, got 80");
    // Integers: the value exactly, the bounds as the doubles' texts.
    EXPECT_EQ(message([] { check_range("k", 5000, Range::closed(2, 1000)); }),
              "k must be in [2, 1000], got 5000");
    EXPECT_EQ(
        message([] { check_range("samples", std::int64_t{123456789012}, Range::closed(1, 1e8)); }),
        "samples must be in [1, 1e8], got 123456789012");
    EXPECT_EQ(message([] { check_range("n", std::size_t{0}, Range::closed(1, 64)); }),
              "n must be in [1, 64], got 0");
}

TEST(FormatNumber, ShortestTextFixedForModerateExponents) {
    EXPECT_EQ(format_number(0), "0");
    EXPECT_EQ(format_number(1000), "1000");
    EXPECT_EQ(format_number(100000), "100000");
    EXPECT_EQ(format_number(0.5), "0.5");
    EXPECT_EQ(format_number(0.005), "0.005");
    EXPECT_EQ(format_number(0.0001), "0.0001");
    EXPECT_EQ(format_number(-45), "-45");
    EXPECT_EQ(format_number(0.1 + 0.2), "0.30000000000000004");  // reads back exactly
    EXPECT_EQ(format_number(1e6), "1e6");
    EXPECT_EQ(format_number(3.6e6), "3.6e6");
    EXPECT_EQ(format_number(1e8), "1e8");
    EXPECT_EQ(format_number(1e-6), "1e-6");
    EXPECT_EQ(format_number(-2.5e-7), "-2.5e-7");
    EXPECT_EQ(format_number(kInf), "inf");
    EXPECT_EQ(Range::open_closed(0.05, 10).to_string(), "(0.05, 10]");
    EXPECT_EQ(Range::closed(1e-6, 0.1).to_string(), "[1e-6, 0.1]");
}

}  // namespace
}  // namespace rgbd
