// Tests of frame-set grouping (sensors/network/frame_grouper.hpp): full sets from phase-aligned
// sensors, spread <= tolerance for random phases, no frame used twice, missing sensors,
// late frames, and waiting for the horizon.
#include "sensors/network/frame_grouper.hpp"

#include <gtest/gtest.h>

#include <limits>
#include <random>
#include <set>

namespace rgbd::sensors::net {
namespace {

constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kFlush = std::numeric_limits<std::int64_t>::max();

TEST(FrameGrouper, AlignedSensorsGiveFullSets) {
    FrameGrouper g(3, 16 * kMs);
    for (int f = 0; f < 10; ++f)
        for (std::size_t s = 0; s < 3; ++s) g.add(s, f * 33 * kMs + static_cast<int>(s) * kMs, f);
    std::vector<io::FrameSet> sets;
    g.form(kFlush, sets);
    ASSERT_EQ(sets.size(), 10u);
    for (int f = 0; f < 10; ++f) {
        EXPECT_EQ(sets[f].set, f);
        EXPECT_EQ(sets[f].frames, (std::vector<std::int64_t>{f, f, f}));
        EXPECT_EQ(sets[f].spread_ns, 2 * kMs);
        EXPECT_EQ(sets[f].time_ns, f * 33 * kMs + kMs);
    }
}

TEST(FrameGrouper, RandomPhasesKeepSpreadWithinToleranceAndUseFramesOnce) {
    std::mt19937 rng(3);
    std::uniform_int_distribution<std::int64_t> phase(0, 33 * kMs);
    const std::size_t n = 8;
    FrameGrouper g(n, 10 * kMs);
    std::vector<std::int64_t> phases(n);
    for (auto& p : phases) p = phase(rng);
    std::vector<io::FrameSet> sets;
    for (int f = 0; f < 200; ++f) {
        for (std::size_t s = 0; s < n; ++s) g.add(s, f * 33 * kMs + phases[s], f);
        g.form(f * 33 * kMs - 100 * kMs, sets);
    }
    g.form(kFlush, sets);
    std::vector<std::set<std::int64_t>> used(n);
    for (const auto& set : sets) {
        EXPECT_LE(set.spread_ns, 10 * kMs);
        for (std::size_t s = 0; s < n; ++s)
            if (set.frames[s] >= 0) {
                EXPECT_TRUE(used[s].insert(set.frames[s]).second);
            }
    }
    for (std::size_t s = 0; s < n; ++s) EXPECT_EQ(used[s].size(), 200u);
    EXPECT_EQ(g.late(), 0);
}

TEST(FrameGrouper, MissingSensorIsMarkedAndHorizonIsRespected) {
    FrameGrouper g(2, 16 * kMs);
    g.add(0, 0, 0);
    g.add(1, 0, 0);
    g.add(0, 33 * kMs, 1);  // sensor 1 lost frame 1
    g.add(0, 66 * kMs, 2);
    g.add(1, 67 * kMs, 1);
    std::vector<io::FrameSet> sets;
    g.form(40 * kMs, sets);  // only the first window [0, 16] is closed before 40 ms
    ASSERT_EQ(sets.size(), 1u);
    g.form(60 * kMs, sets);  // [33, 49] closed
    ASSERT_EQ(sets.size(), 2u);
    EXPECT_EQ(sets[1].frames, (std::vector<std::int64_t>{1, -1}));
    EXPECT_EQ(sets[1].spread_ns, 0);
    g.form(kFlush, sets);
    ASSERT_EQ(sets.size(), 3u);
    EXPECT_EQ(sets[2].frames, (std::vector<std::int64_t>{2, 1}));
    // A frame older than what was formed is late: recorded elsewhere, in no set.
    EXPECT_FALSE(g.add(1, 30 * kMs, 7));
    EXPECT_EQ(g.late(), 1);
}

TEST(FrameGrouper, CompleteWindowsAreFormedEarlyWhenAsked) {
    FrameGrouper g(2, 16 * kMs, true);
    g.add(0, 0, 0);
    g.add(1, 2 * kMs, 0);
    g.add(0, 33 * kMs, 1);
    std::vector<io::FrameSet> sets;
    g.form(-1000 * kMs, sets);  // long before the horizon: the complete window goes at once
    ASSERT_EQ(sets.size(), 1u);
    EXPECT_EQ(sets[0].frames, (std::vector<std::int64_t>{0, 0}));
    g.form(40 * kMs, sets);  // [33, 49] is incomplete and not closed: it waits
    EXPECT_EQ(sets.size(), 1u);
    g.add(1, 35 * kMs, 1);
    g.form(40 * kMs, sets);
    ASSERT_EQ(sets.size(), 2u);
    EXPECT_EQ(sets[1].frames, (std::vector<std::int64_t>{1, 1}));
}

}  // namespace
}  // namespace rgbd::sensors::net
