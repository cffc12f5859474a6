// The tool driver's text helpers: help texts that read their numbers from the options structs
// (with_numbers), message numbers (formatted), frame ranges (parse_range) and the option a
// usage error is about (option_named_by).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "cli/common/tool.hpp"
#include "toolkit/error.hpp"

namespace {

namespace cli = rgbd::cli;
namespace po = boost::program_options;

TEST(DriverText, WithNumbersFillsEveryHoleInOrderAsShortNumbers) {
    EXPECT_EQ(cli::with_numbers("default {} for --distance, {} for --density", {16, 0.2}),
              "default 16 for --distance, 0.2 for --density");
    EXPECT_EQ(cli::with_numbers("{}{} and 1e{}", {1e6, 0.1, 3}), "1e60.1 and 1e3");
    EXPECT_EQ(cli::with_numbers("no numbers", {}), "no numbers");
    // A text and its values that do not match are a programming error, not a silent help.
    EXPECT_THROW(cli::with_numbers("{} and {}", {1}), rgbd::Error);
    EXPECT_THROW(cli::with_numbers("{}", {1, 2}), rgbd::Error);
}

TEST(DriverText, FormattedIsPrintfIntoAStringOfAnyLength) {
    EXPECT_EQ(cli::formatted("fitness %.3f, rmse %.2f mm", 0.7220413, 6.3149),
              "fitness 0.722, rmse 6.31 mm");
    EXPECT_EQ(cli::formatted("%s", std::string(5000, 'x').c_str()).size(), 5000u);
    EXPECT_EQ(cli::formatted("%s", ""), "");
}

TEST(DriverText, ParseRangeReadsSingleClosedOpenAndSteppedRanges) {
    EXPECT_EQ(cli::parse_range("3", 10), (std::vector<long long>{3}));
    EXPECT_EQ(cli::parse_range("2:5", 10), (std::vector<long long>{2, 3, 4}));
    EXPECT_EQ(cli::parse_range("0:10:4", 10), (std::vector<long long>{0, 4, 8}));
    EXPECT_EQ(cli::parse_range("7:", 9), (std::vector<long long>{7, 8}));
    EXPECT_THROW(cli::parse_range("a:b", 10), cli::UsageError);
    EXPECT_THROW(cli::parse_range("-1", 10), cli::UsageError);
}

TEST(DriverText, OptionNamedByTheValueOrTheFieldTheMessageNames) {
    po::options_description d;
    d.add_options()("std-ratio", po::value<double>())("noise-model", po::value<std::string>())(
        "k", po::value<int>())("alpha", po::value<double>());
    po::variables_map vm;
    const char* argv[] = {"t", "--std-ratio", "-1", "--noise-model", "bogus", "--k", "0"};
    po::store(po::parse_command_line(7, argv, d), vm);
    EXPECT_EQ(cli::option_named_by("statistical: std_ratio must be in (0, 100], got -1", vm),
              " (--std-ratio)");
    EXPECT_EQ(cli::option_named_by("unknown noise model 'bogus'", vm), " (--noise-model)");
    EXPECT_EQ(cli::option_named_by("neighbours must be in [1, 1000], got 0", vm), " (--k)");
    // A message that names its option already, or fits no given option, gets nothing.
    EXPECT_EQ(cli::option_named_by("--k must be positive", vm), "");
    EXPECT_EQ(cli::option_named_by("radius must be > 0", vm), "");
}

}  // namespace
