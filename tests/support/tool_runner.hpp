// Runs built tools from contract tests: a shell command line in a per-process scratch folder,
// with $BIN pointing at the tools, capturing exit code, stdout and stderr.
#pragma once

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

namespace rgbd::test {

struct Outcome {
    int code = -1;
    std::string out, err;
};

inline std::string slurp(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

inline int line_count(const std::string& s) {
    int n = 0;
    for (char c : s) n += c == '\n';
    return n;
}

/// A JSON file (a tool's --metrics or report), parsed.
inline nlohmann::json read_json(const std::filesystem::path& p) {
    return nlohmann::json::parse(slurp(p));
}

/// Removes `dir` when the test process ends if every test of the process passed (a failed
/// test's files stay for a look) and RGBD_KEEP_SCRATCH is not set. ctest runs each test in a
/// process of its own: without this every run of the suite left about 380 folders, up to
/// 0.7 GB each for the capture tests, and a day of runs filled the disk.
inline void remove_at_exit(const std::filesystem::path& dir) {
    struct Cleanup {
        std::vector<std::filesystem::path> dirs;
        ~Cleanup() {
            if (std::getenv("RGBD_KEEP_SCRATCH") || !::testing::UnitTest::GetInstance()->Passed())
                return;
            std::error_code ec;
            for (const auto& d : dirs) std::filesystem::remove_all(d, ec);
        }
    };
    static Cleanup cleanup;
    cleanup.dirs.push_back(dir);
}

/// A fresh scratch folder per test process: temp/<prefix>_<pid>, removed at the end of a
/// process whose tests passed (remove_at_exit). A folder of that name can only be left over
/// from an earlier, finished process that had the same pid (ctest runs every test in its own
/// process; pids are reused), so it is emptied first: stale files made cli_test's fs::copy
/// into "badrig" fail with "File exists". Call it once per process.
inline std::filesystem::path scratch_dir(const std::string& prefix) {
    std::filesystem::path p =
        std::filesystem::temp_directory_path() / (prefix + "_" + std::to_string(::getpid()));
    std::filesystem::remove_all(p);
    std::filesystem::create_directories(p);
    remove_at_exit(p);
    return p;
}

/// Runs `command` with bash in `dir` (BIN = the tools' folder, stdin = /dev/null).
inline Outcome run_in(const std::filesystem::path& dir, const std::string& command) {
    static int counter = 0;
    const std::filesystem::path out = dir / ("out" + std::to_string(counter) + ".txt");
    const std::filesystem::path err = dir / ("err" + std::to_string(counter++) + ".txt");
    const std::string line = "BIN=" + std::string(RGBD_BINARY_DIR) + "; cd " + dir.string() +
                             " && ( " + command + " ) >" + out.string() + " 2>" + err.string() +
                             " </dev/null";
    const int status = std::system(("bash -c '" + line + "'").c_str());
    Outcome r;
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.out = slurp(out);
    r.err = slurp(err);
    return r;
}

/// The failure contract of a tool run (cli/README.md, common behaviour): exit `code` (1 a
/// runtime failure, 2 a usage error), stderr "<tool>: error: ..." on one line (a usage error
/// adds the "Try '<tool> --help'" line), and the output file `output` in `dir` not written,
/// not even as a temporary file left behind.
inline void expect_failure(const Outcome& r, int code, const std::string& tool,
                           const std::filesystem::path& dir,
                           const std::string& output = "never.ply") {
    EXPECT_EQ(r.code, code) << r.err;
    EXPECT_EQ(r.err.rfind(tool + ": error: ", 0), 0u) << r.err;
    EXPECT_EQ(line_count(r.err), code == 2 ? 2 : 1) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir / output));
    for (const auto& e : std::filesystem::directory_iterator(dir))
        EXPECT_EQ(e.path().filename().string().find("." + output), std::string::npos) << e.path();
}

}  // namespace rgbd::test

/// The scratch folder and command runner of a tool test file: defines `temp_root()` (a
/// scratch_dir named `prefix`, made once per test process) and `run(command)` (run_in that
/// folder) in the including file's anonymous namespace, with Outcome, slurp, line_count and
/// read_json.
#define RGBD_TOOL_TEST_SCRATCH(prefix)                                             \
    using rgbd::test::line_count;                                                  \
    using rgbd::test::Outcome;                                                     \
    using rgbd::test::read_json;                                                   \
    using rgbd::test::slurp;                                                       \
    std::filesystem::path temp_root() {                                            \
        static const std::filesystem::path root = rgbd::test::scratch_dir(prefix); \
        return root;                                                               \
    }                                                                              \
    rgbd::test::Outcome run(const std::string& command) {                          \
        return rgbd::test::run_in(temp_root(), command);                           \
    }
