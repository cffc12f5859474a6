// Issue 18 item 4: progress a user can follow anywhere. In log mode (stderr not a terminal) a
// stage that runs longer than a second prints a "started" line, a line at least every
// heartbeat while it runs even when the algorithm reports nothing, and "done in N s"; the
// percentages never go backwards; quick stages print nothing. On a terminal the bar never
// goes backwards either.
#include <gtest/gtest.h>

#include <chrono>
#include <iostream>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "cli/common/tool.hpp"

namespace {

using rgbd::cli::ProgressBar;
using Mode = ProgressBar::Mode;

/// Captures std::cerr for its lifetime.
class CaptureCerr {
public:
    CaptureCerr() : old_(std::cerr.rdbuf(buffer_.rdbuf())) {}
    ~CaptureCerr() { std::cerr.rdbuf(old_); }
    std::string text() const { return buffer_.str(); }

private:
    std::stringstream buffer_;
    std::streambuf* old_;
};

std::vector<std::string> lines(const std::string& text) {
    std::vector<std::string> out;
    std::istringstream in(text);
    for (std::string line; std::getline(in, line);) out.push_back(line);
    return out;
}

void sleep_s(double s) { std::this_thread::sleep_for(std::chrono::duration<double>(s)); }

TEST(ProgressBar, LogModeHeartbeatWhileTheAlgorithmIsSilent) {
    // Times are checked loosely (the test machine may be loaded): a line at least every two
    // heartbeats, in order, with the percentage that was reported.
    constexpr double kBeat = 0.5;
    CaptureCerr capture;
    {
        ProgressBar bar("tool: stage", Mode::kLog, kBeat);
        bar.update(0.9);
        sleep_s(0.2);
        bar.update(0.49);  // a part restarting its own fraction: must not show 49%
        sleep_s(3.3);      // no report at all for over three seconds
    }
    const auto got = lines(capture.text());
    ASSERT_GE(got.size(), 4u) << capture.text();
    const std::regex started(R"(tool: stage: started, 90% after (1\.[0-9]) s)");
    const std::regex beat(R"(tool: stage: (?:started, )?(\d+)% after ([0-9.]+) s)");
    const std::regex done(R"(tool: stage: done in ([0-9.]+) s)");
    std::smatch m;
    EXPECT_TRUE(std::regex_match(got.front(), m, started)) << got.front();
    ASSERT_TRUE(std::regex_match(got.back(), m, done)) << got.back();
    EXPECT_GE(std::stod(m[1]), 3.5);
    double last_t = 0;
    for (std::size_t i = 0; i + 1 < got.size(); ++i) {
        ASSERT_TRUE(std::regex_match(got[i], m, beat)) << got[i];
        EXPECT_EQ(std::stoi(m[1]), 90) << "percent went backwards: " << got[i];
        const double t = std::stod(m[2]);
        if (i > 0) {
            EXPECT_LE(t - last_t, 2 * kBeat) << "no line for too long: " << got[i];
        }
        EXPECT_GT(t, last_t);
        last_t = t;
    }
}

TEST(ProgressBar, LogModeQuickStagePrintsNothing) {
    CaptureCerr capture;
    {
        ProgressBar bar("tool: quick", Mode::kLog);
        bar.update(0.5);
        bar.update(1.0);
    }
    EXPECT_EQ(capture.text(), "");
}

TEST(ProgressBar, LogModeStageEndedByAnErrorSaysStopped) {
    CaptureCerr capture;
    try {
        ProgressBar bar("tool: failing", Mode::kLog, 10.0);
        sleep_s(1.5);
        throw std::runtime_error("boom");
    } catch (const std::runtime_error&) {
    }
    const auto got = lines(capture.text());
    ASSERT_EQ(got.size(), 2u) << capture.text();
    EXPECT_NE(got[0].find("tool: failing: started, 0% after 1."), std::string::npos);
    EXPECT_NE(got[1].find("tool: failing: stopped after "), std::string::npos) << got[1];
}

TEST(ProgressBar, TerminalBarNeverGoesBackwards) {
    CaptureCerr capture;
    {
        ProgressBar bar("tool: align", Mode::kTerminal);
        bar.update(0.3);
        bar.update(0.9);
        bar.update(0.49);
        bar.update(0.2);
        bar.update(1.0);
    }
    // Every redraw starts with \r; the percentages drawn must never decrease.
    const std::string text = capture.text();
    const std::regex drawn(R"((\d+)%)");
    std::vector<int> shown;
    for (auto it = std::sregex_iterator(text.begin(), text.end(), drawn);
         it != std::sregex_iterator(); ++it)
        shown.push_back(std::stoi((*it)[1]));
    EXPECT_EQ(shown, (std::vector<int>{30, 90, 100})) << text;
}

TEST(ProgressBar, OffModePrintsNothing) {
    CaptureCerr capture;
    {
        ProgressBar bar("tool: quiet", Mode::kOff, 0.05);
        bar.update(0.5);
        sleep_s(0.1);
    }
    EXPECT_EQ(capture.text(), "");
}

}  // namespace
