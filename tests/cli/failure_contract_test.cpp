// Issue 21 item 4, over every tool: a failed run (a missing, garbage or truncated input, a
// broken capture folder, an output folder that does not exist) exits 1 (runtime) or 2
// (usage), never by a signal, prints exactly one line on stderr naming the file and the
// problem, and leaves no output file and no temporary file behind (cli/README.md).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <string>

#include "tests/support/tool_runner.hpp"

namespace fs = std::filesystem;

namespace {

using rgbd::test::line_count;
using rgbd::test::Outcome;

fs::path temp_root() {
    static const fs::path root = rgbd::test::scratch_dir("rgbd_failure_contract_test");
    return root;
}

Outcome run(const std::string& command) { return rgbd::test::run_in(temp_root(), command); }

/// The inputs: every one is wrong in a way a reader must report, naming the file.
void make_inputs() {
    const fs::path r = temp_root();
    std::ofstream(r / "garbage.ply") << "this is not a ply file\n";
    std::ofstream(r / "garbage.off") << "OFF\n3 1 0\n0 0 0\n1 0\n";
    std::ofstream(r / "garbage.json") << "{ \"format\": \"rgbd-capture\", \n";
    // A PLY stream document that promises 100 vertices and ends after two.
    std::ofstream(r / "truncated.ply")
        << "ply\nformat ascii 1.0\ncomment rgbd:stream 1\nelement vertex 100\n"
           "property float x\nproperty float y\nproperty float z\nend_header\n0 0 1\n1 0 1\n";
    // A valid three-point stream, for the unwritable-output case.
    std::ofstream(r / "small.ply")
        << "ply\nformat ascii 1.0\ncomment rgbd:stream 1\nelement vertex 3\n"
           "property float x\nproperty float y\nproperty float z\nend_header\n"
           "0 0 1\n0.01 0 1\n0 0.01 1\n";
    fs::create_directories(r / "badcap");
    std::ofstream(r / "badcap" / "rig.json") << "{\"format\": \"rgbd-capture\", \"version\": 7}\n";
}

std::set<std::string> entries() {
    std::set<std::string> names;
    for (const auto& e : fs::directory_iterator(temp_root()))
        names.insert(e.path().filename().string());
    return names;
}

struct Case {
    const char* command;  ///< run in temp_root() with $BIN = the tools' folder
    const char* names;    ///< the stderr line must contain this (the file)
};

// Outputs are named out.* or out/; none may exist after the run.
const Case kCases[] = {
    {"rgbd-cloud badcap -o out.ply", "rig.json"},
    {"rgbd-cloud no-such-capture -o out.ply", "no-such-capture"},
    {"rgbd-clean truncated.ply -o out.ply", "truncated.ply"},
    {"rgbd-clean --statistical small.ply -o no-such-folder/out.ply", "no-such-folder/out.ply"},
    {"rgbd-align garbage.ply -o out.ply", "garbage.ply"},
    {"rgbd-mesh truncated.ply -o out.ply", "truncated.ply"},
    {"rgbd-fill truncated.ply -o out.ply", "truncated.ply"},
    {"rgbd-upsample truncated.ply -o out.ply", "truncated.ply"},
    {"rgbd-eval garbage.off --reference garbage.off -o out.json", "garbage.off"},
    {"rgbd-reconstruct badcap -o out.ply --report out_report -q", "rig.json"},
    {"rgbd-info garbage.ply", "garbage.ply"},
    {"rgbd-render truncated.ply -o out.png", "truncated.ply"},
    {"rgbd-synth garbage.off -o out_capture", "garbage.off"},
    {"rgbd-capture --rig garbage.json -o out_capture", "garbage.json"},
    {"rgbd-capture --rig badcap/rig.json --live out.ply", "rig.json"},
    {"rgbd-node --sensor playback:badcap --hub tcp://127.0.0.1:9", "rig.json"},
    {"rgbd-calibrate badcap -o out.json", "rig.json"},
    {"rgbd-capture --rig badcap/rig.json --video out_video", "rig.json"},
    {"rgbd-view no-such-video --port 0 --duration-s 1", "no-such-video"},
};

}  // namespace

TEST(FailureContract, EveryToolFailsWithOneLineNamingTheFileAndNoOutput) {
    make_inputs();
    const std::set<std::string> before = entries();
    const std::regex kCaptured("(out|err)[0-9]+\\.txt");
    for (const Case& c : kCases) {
        SCOPED_TRACE(c.command);
        const Outcome r = run(std::string("$BIN/") + c.command);
        // run_in reports -1 for a signal; bash reports 128+N when the tool died by signal N.
        EXPECT_TRUE(r.code == 1 || r.code == 2) << "exit " << r.code << ": " << r.err;
        EXPECT_EQ(line_count(r.err), 1) << r.err;
        EXPECT_NE(r.err.find(c.names), std::string::npos) << r.err;
        EXPECT_NE(r.err.find("error"), std::string::npos) << r.err;
        EXPECT_TRUE(r.out.empty()) << r.out.substr(0, 200);
        for (const std::string& name : entries()) {
            if (before.count(name) || std::regex_match(name, kCaptured))
                continue;  // the inputs and run_in's captured stdout/stderr
            ADD_FAILURE() << "left behind: " << name;
            fs::remove_all(temp_root() / name);
        }
    }
}
