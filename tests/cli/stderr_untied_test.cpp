// Issue 39 item 3: std::cerr must not be tied to std::cout in a tool. A tie makes every
// `std::cerr <<` flush std::cout first, from whichever thread writes the message: a warning of
// rgbd-capture --live -'s control thread would then flush stdout while the tool's own thread is
// streaming PLY into it (a data race that can corrupt the stream). run_tool unties std::cerr
// next to sync_with_stdio(false). The check is on the behaviour, deterministically: a body
// leaves bytes in std::cout's buffer, another thread writes std::cerr, and stdout (a file
// here) must still be empty; only the driver's flush at exit writes the bytes. Tied, the
// message would have flushed them at once (what the test sees without the untie).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>
#include <thread>

#include "cli/common/tool.hpp"

namespace {

namespace fs = std::filesystem;
namespace cli = rgbd::cli;

/// Bytes written so far to the file open as descriptor `fd`.
long long file_size(int fd) {
    struct stat st {};
    return ::fstat(fd, &st) == 0 ? static_cast<long long>(st.st_size) : -1;
}

TEST(StderrUntied, AThreadsMessageDoesNotFlushTheToolsStdout) {
    const fs::path path = fs::temp_directory_path() / "rgbd_stderr_untied_test.out";
    std::fflush(stdout);
    std::cout.flush();
    const int saved = ::dup(STDOUT_FILENO);
    const int file = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ASSERT_GE(file, 0);
    ASSERT_GE(::dup2(file, STDOUT_FILENO), 0);

    long long during = -1;
    bool tied = true;
    cli::ToolSpec spec;
    spec.name = "rgbd-test";
    spec.usage = "rgbd-test";
    spec.writes_stream = false;
    spec.reads_stream = false;
    std::ostringstream messages;  // the thread's message goes here, not to the test's stderr
    const auto body = [&](cli::Context&) {
        tied = std::cerr.tie() != nullptr;
        std::streambuf* old = std::cerr.rdbuf(messages.rdbuf());
        std::cout << "ply data";  // stays in std::cout's buffer: no newline-flush, no endl
        std::thread([] { std::cerr << "rgbd-test: warning: from another thread\n"; }).join();
        during = file_size(STDOUT_FILENO);
        std::cerr.rdbuf(old);
    };
    char name[] = "rgbd-test";
    char* argv[] = {name, nullptr};
    const int code = cli::run_tool(1, argv, spec, body);
    std::cout.flush();
    const long long after = file_size(STDOUT_FILENO);
    ::dup2(saved, STDOUT_FILENO);
    ::close(saved);
    ::close(file);
    fs::remove(path);

    EXPECT_EQ(code, 0);
    EXPECT_FALSE(tied) << "std::cerr is tied to " << std::cerr.tie();
    EXPECT_EQ(during, 0) << "the message on std::cerr flushed the tool's stdout";
    EXPECT_EQ(after, 8);  // "ply data", written by the flush
    EXPECT_NE(messages.str().find("from another thread"), std::string::npos);
}

}  // namespace
