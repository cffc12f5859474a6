// option_named_by: the option a library message is about, found from the values and names the
// message quotes; nothing when it fits none or several.
#include "toolkit/option_names.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace {

using rgbd::GivenOption;
using rgbd::option_named_by;

const std::vector<GivenOption> kGiven = {{"std-ratio", "-1"},
                                         {"noise-model", "bogus"},
                                         {"z-min", "10"},
                                         {"alpha", "1e300"},
                                         {"theta-max-deg", "95"}};

TEST(OptionNames, AQuotedValueNamesItsOption) {
    EXPECT_EQ(option_named_by("unknown noise model 'bogus' (expected ...)", kGiven),
              " (--noise-model)");
    EXPECT_EQ(option_named_by("robust deviations must be in [0, 1000], got 1e300", kGiven),
              " (--alpha)");
    // "got 1" is not "got 10", nor "got 1.5".
    EXPECT_EQ(option_named_by("must be in [0, 5], got 1", {{"a", "1"}, {"b", "10"}}), " (--a)");
    EXPECT_EQ(option_named_by("must be in [0, 5], got 10", {{"a", "1"}, {"b", "10"}}), " (--b)");
    EXPECT_EQ(option_named_by("must be in [0, 1], got 1.5", {{"a", "1"}}), "");
}

TEST(OptionNames, AFieldNameOrWordNamesItsOption) {
    EXPECT_EQ(option_named_by("statistical: std_ratio must be positive", kGiven), " (--std-ratio)");
    EXPECT_EQ(option_named_by("depth window z_min_m must be >= 0", kGiven), " (--z-min)");
    EXPECT_EQ(option_named_by("density outliers: theta_max must be in (0, 89] degrees", kGiven),
              " (--theta-max-deg)");
    EXPECT_EQ(option_named_by("alpha must be finite", kGiven), " (--alpha)");
}

TEST(OptionNames, NothingWhenNamedAlreadyAmbiguousOrUnrelated) {
    EXPECT_EQ(option_named_by("--alpha must be finite", kGiven), "");
    EXPECT_EQ(option_named_by("two values got -1", {{"a", "-1"}, {"b", "-1"}}), "");
    EXPECT_EQ(option_named_by("the mesh has no faces", kGiven), "");
    EXPECT_EQ(option_named_by("got 5", {{"empty", ""}}), "");
    EXPECT_EQ(option_named_by("anything", {}), "");
}

}  // namespace
