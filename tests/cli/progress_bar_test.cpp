// Issue 18 item 4: progress a user can follow anywhere. In log mode (stderr not a terminal) a
// stage that runs longer than a second prints a "started" line, lines at each heartbeat while
// it runs even when the algorithm reports nothing, and "done in N s"; the percentages never go
// backwards; quick stages print nothing. On a terminal the bar never goes backwards either.
// No check depends on the machine's speed (issue 39): the tests wait for the lines the bar
// owes them, under a hang guard, instead of sleeping a fixed time and timing the lines.
#include <gtest/gtest.h>

#include <chrono>
#include <iostream>
#include <mutex>
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

/// A stream buffer that other threads may write while the test reads it.
class LockedBuffer : public std::streambuf {
public:
    std::string text() const {
        std::lock_guard lock(mutex_);
        return text_;
    }

protected:
    std::streamsize xsputn(const char* s, std::streamsize n) override {
        std::lock_guard lock(mutex_);
        text_.append(s, static_cast<std::size_t>(n));
        return n;
    }
    int_type overflow(int_type c) override {
        if (traits_type::eq_int_type(c, traits_type::eof())) return traits_type::not_eof(c);
        std::lock_guard lock(mutex_);
        text_.push_back(traits_type::to_char_type(c));
        return c;
    }

private:
    mutable std::mutex mutex_;
    std::string text_;
};

/// Captures std::cerr for its lifetime; text() may be read while the bar's thread writes.
class CaptureCerr {
public:
    CaptureCerr() : old_(std::cerr.rdbuf(&buffer_)) {}
    ~CaptureCerr() { std::cerr.rdbuf(old_); }
    std::string text() const { return buffer_.text(); }

private:
    LockedBuffer buffer_;
    std::streambuf* old_;
};

std::vector<std::string> lines(const std::string& text) {
    std::vector<std::string> out;
    std::istringstream in(text);
    for (std::string line; std::getline(in, line);) out.push_back(line);
    return out;
}

void sleep_s(double s) { std::this_thread::sleep_for(std::chrono::duration<double>(s)); }

/// Not a speed limit: how long a test waits for lines the bar's thread owes it before it gives
/// up (a bar that never prints). The lines come after 1 s and every heartbeat on a quiet
/// machine; a loaded one delays them, which must not change the verdict (issue 39).
constexpr double kHangGuardS = 120.0;

/// Waits until `capture` holds at least `count` lines; false after kHangGuardS.
bool wait_for_lines(const CaptureCerr& capture, std::size_t count) {
    const auto give_up =
        std::chrono::steady_clock::now() + std::chrono::duration<double>(kHangGuardS);
    while (lines(capture.text()).size() < count) {
        if (std::chrono::steady_clock::now() > give_up) return false;
        sleep_s(0.05);
    }
    return true;
}

TEST(ProgressBar, LogModeHeartbeatWhileTheAlgorithmIsSilent) {
    // What is checked holds on any machine, however loaded: the first line comes no earlier
    // than a second into the stage and says "started"; lines keep coming while the algorithm
    // reports nothing (two heartbeats after "started" here), in time order, with the highest
    // percentage reported (never the lower one reported later); the last says "done" no
    // earlier than the last heartbeat. How closely lines follow the heartbeat period is the
    // scheduler's business, not the verdict's.
    constexpr double kBeat = 0.5;
    CaptureCerr capture;
    {
        ProgressBar bar("tool: stage", Mode::kLog, kBeat);
        bar.update(0.9);
        sleep_s(0.2);
        bar.update(0.49);  // a part restarting its own fraction: must not show 49%
        // No report at all from here on.
        ASSERT_TRUE(wait_for_lines(capture, 3)) << capture.text();
    }
    const auto got = lines(capture.text());
    ASSERT_GE(got.size(), 4u) << capture.text();
    const std::regex started(R"(tool: stage: started, 90% after ([0-9.]+) s)");
    const std::regex beat(R"(tool: stage: (\d+)% after ([0-9.]+) s)");
    const std::regex done(R"(tool: stage: done in ([0-9.]+) s)");
    std::smatch m;
    ASSERT_TRUE(std::regex_match(got.front(), m, started)) << got.front();
    double last_t = std::stod(m[1]);
    EXPECT_GE(last_t, 1.0);
    for (std::size_t i = 1; i + 1 < got.size(); ++i) {
        ASSERT_TRUE(std::regex_match(got[i], m, beat)) << got[i];
        EXPECT_EQ(std::stoi(m[1]), 90) << "percent went backwards: " << got[i];
        const double t = std::stod(m[2]);
        EXPECT_GT(t, last_t);
        last_t = t;
    }
    ASSERT_TRUE(std::regex_match(got.back(), m, done)) << got.back();
    EXPECT_GE(std::stod(m[1]), last_t);
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
        ProgressBar bar("tool: failing", Mode::kLog, 1000.0);
        ASSERT_TRUE(wait_for_lines(capture, 1)) << capture.text();  // "started" after 1 s
        throw std::runtime_error("boom");
    } catch (const std::runtime_error&) {
    }
    const auto got = lines(capture.text());
    ASSERT_EQ(got.size(), 2u) << capture.text();
    std::smatch m;
    ASSERT_TRUE(
        std::regex_match(got[0], m, std::regex(R"(tool: failing: started, 0% after ([0-9.]+) s)")))
        << got[0];
    EXPECT_GE(std::stod(m[1]), 1.0);
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
