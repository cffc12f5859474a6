// Issue 21 item 4, over every tool: a failed run (a missing, garbage or truncated input, a
// broken capture folder, an output folder that does not exist) exits 1 (runtime) or 2
// (usage), never by a signal, prints exactly one line on stderr naming the file and the
// problem, and leaves no output file and no temporary file behind (cli/README.md). A bad option
// value exits 2 with one error line naming the option (and the usage hint), before any input
// is read. validation/robustness/option_sweep.py tries every option of every tool.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <string>

#include "tests/support/ellipsoid_off.hpp"
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
    {"rgbd-clean --statistical small.ply -o out.ply --metrics no-such-folder/out.json",
     "no-such-folder/out.json"},
    {"rgbd-clean --statistical small.ply -o out.ply --metrics badcap", "badcap"},
    {"rgbd-mesh small.ply -o badcap", "badcap"},
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

// A stream tool checks where its output goes before it reads anything: the error names the
// missing output folder or the terminal, not the garbage input it never read.
TEST(FailureContract, OutputIsCheckedBeforeTheWork) {
    make_inputs();
    for (const char* tool : {"rgbd-clean", "rgbd-align", "rgbd-mesh", "rgbd-fill"}) {
        SCOPED_TRACE(tool);
        const Outcome folder =
            run(std::string("$BIN/") + tool + " garbage.ply -o no-such-folder/out.ply");
        EXPECT_EQ(folder.code, 1) << folder.err;
        EXPECT_NE(folder.err.find("no-such-folder"), std::string::npos) << folder.err;
        EXPECT_EQ(folder.err.find("garbage.ply"), std::string::npos) << folder.err;
        // script(1) gives the tool a terminal as stdout (and stderr: its messages come out on
        // script's stdout).
        const Outcome tty =
            run(std::string("script -qec \"$BIN/") + tool + " garbage.ply\" /dev/null");
        EXPECT_EQ(tty.code, 2) << tty.out;
        EXPECT_NE(tty.out.find("refusing to write binary data to a terminal"), std::string::npos)
            << tty.out;
        EXPECT_EQ(tty.out.find("garbage.ply"), std::string::npos) << tty.out;
    }
    // Tools that write a file of their own (a mesh after the whole method, a picture, JSON).
    for (const char* command :
         {"rgbd-reconstruct badcap -q -o no-such-folder/out.ply",
          "rgbd-render garbage.ply -o "
          "no-such-folder/out.png",
          "rgbd-eval garbage.ply --reference garbage.off -o no-such-folder/out.json",
          "rgbd-calibrate badcap -o no-such-folder/out.json"}) {
        SCOPED_TRACE(command);
        const Outcome r = run(std::string("$BIN/") + command);
        EXPECT_EQ(r.code, 1) << r.err;
        EXPECT_EQ(line_count(r.err), 1) << r.err;
        EXPECT_NE(r.err.find("no-such-folder"), std::string::npos) << r.err;
        EXPECT_FALSE(fs::exists(temp_root() / "no-such-folder"));
    }
}

// Input that arrives late and is bad: still exactly the one error line (no progress heartbeat
// before it, which a stage started before its input would print after a second).
TEST(FailureContract, SlowBadInputGivesOneLine) {
    for (const char* tool : {"rgbd-clean", "rgbd-upsample"}) {
        SCOPED_TRACE(tool);
        const Outcome r =
            run(std::string("(sleep 1.3; echo garbage) | $BIN/") + tool + " -o out.ply");
        EXPECT_EQ(r.code, 1) << r.err;
        EXPECT_EQ(line_count(r.err), 1) << r.err;
        EXPECT_FALSE(fs::exists(temp_root() / "out.ply"));
    }
}

namespace {

struct BadValue {
    const char* command;  ///< run in temp_root() with $BIN = the tools' folder
    const char* option;   ///< the error line must name it
};

// One or more bad values per tool. Most tools check their options before they read an
// input; rgbd-calibrate reads the capture first, so it gets a valid one (goodcap).
const BadValue kBadValues[] = {
    {"rgbd-cloud badcap --crop-radius-m -1 -o out.ply", "--crop-radius-m"},
    {"rgbd-cloud badcap --z-min -1 -o out.ply", "--z-min"},
    {"rgbd-clean small.ply --statistical --std-ratio nan -o out.ply", "--std-ratio"},
    {"rgbd-clean small.ply --noise-model kinect_v9 -o out.ply", "--noise-model"},
    {"rgbd-align small.ply --voxel-m -1 -o out.ply", "--voxel-m"},
    {"rgbd-mesh small.ply --target-faces 2 -o out.ply", "--target-faces"},
    {"rgbd-mesh small.ply --method marching -o out.ply", "--method"},
    {"rgbd-fill small.ply --colour-inpaint blur -o out.ply", "--colour-inpaint"},
    {"rgbd-upsample small.ply --theta-max-deg 120 -o out.ply", "--theta-max-deg"},
    // Prose messages that quote the value ("got -1"): the driver names the option.
    {"rgbd-fill small.ply --inpaint-pixel -1 -o out.ply", "--inpaint-pixel"},
    {"rgbd-fill small.ply --max-fit-rms nan -o out.ply", "--max-fit-rms"},
    {"rgbd-fill small.ply --top-min-up 2 -o out.ply", "--top-min-up"},
    {"rgbd-fill small.ply --top-fit-radii -1 -o out.ply", "--top-fit-radii"},
    {"rgbd-render small.ply --width 5 -o out.png", "--width"},
    {"rgbd-render small.ply --point-size 1e300 -o out.png", "--point-size"},
    {"rgbd-eval small.ply --reference small.ply --invented-tau-mm -1 -o out.json",
     "--invented-tau-mm"},
    {"rgbd-eval small.ply --reference small.ply --report-size 3x3 --report out_report -o "
     "out.json",
     "--report-size"},
    {"rgbd-reconstruct badcap --stand sideways -o out.ply -q", "--stand"},
    {"rgbd-reconstruct badcap --upsample 5 -o out.ply -q", "--upsample"},
    {"rgbd-reconstruct badcap --skip nothing -o out.ply -q", "--skip"},
    {"rgbd-info small.ply --threads -1", "--threads"},
    {"rgbd-render small.ply --up 0,0,0 -o out.png", "--up"},
    {"rgbd-synth garbage.off --rig turntable --stops 0 -o out_capture", "--stops"},
    {"rgbd-capture --rig badcap/rig.json --tolerance-ms -1 -o out_capture", "--tolerance-ms"},
    {"rgbd-capture --rig badcap/rig.json --png-compression 12 -o out_capture", "--png-compression"},
    {"rgbd-node --sensor playback:badcap --jpeg-quality 0", "--jpeg-quality"},
    {"rgbd-view no-such-video --port 70000", "--port"},
    {"rgbd-calibrate goodcap --max-plane-mm nan -o out.json", "--max-plane-mm"},
    {"rgbd-calibrate goodcap --max-rms-px -1 -o out.json", "--max-rms-px"},
};

}  // namespace

TEST(FailureContract, BadOptionValuesAreUsageErrorsNamingTheOptionWithoutOutput) {
    make_inputs();
    rgbd::test::write_ellipsoid_off(temp_root() / "blob.off", 32, 16, 0.3, 0.5, 0.25);
    const Outcome synth = run("$BIN/rgbd-synth blob.off -o goodcap --sensors 1 --frames 1 -q");
    ASSERT_EQ(synth.code, 0) << synth.err;
    const std::set<std::string> before = entries();
    const std::regex kCaptured("(out|err)[0-9]+\\.txt");
    for (const BadValue& c : kBadValues) {
        SCOPED_TRACE(c.command);
        const Outcome r = run(std::string("$BIN/") + c.command);
        EXPECT_EQ(r.code, 2) << r.err;
        // "<tool>: error: ... --option ...", then at most the usage hint.
        const std::string tool = std::string(c.command).substr(0, std::string(c.command).find(' '));
        const std::string first = r.err.substr(0, r.err.find('\n'));
        EXPECT_EQ(first.rfind(tool + ": error: ", 0), 0u) << r.err;
        EXPECT_NE(first.find(c.option), std::string::npos) << r.err;
        EXPECT_TRUE(line_count(r.err) == 1 ||
                    (line_count(r.err) == 2 &&
                     r.err.find("\nTry '" + tool + " --help'") != std::string::npos))
            << r.err;
        EXPECT_TRUE(r.out.empty()) << r.out.substr(0, 200);
        for (const std::string& name : entries()) {
            if (before.count(name) || std::regex_match(name, kCaptured)) continue;
            ADD_FAILURE() << "left behind: " << name;
            fs::remove_all(temp_root() / name);
        }
    }
}

namespace {

struct Refused {
    const char* command;  ///< run in temp_root() with $BIN = the tools' folder
    const char* message;  ///< the error line must contain this
};

// Issue 39 item 8: values a tool used to accept (exit 0), and options it used to ignore in a
// mode they do not apply to. The checks are declared once per tool (ToolSpec::ranges and
// scopes) or made for every option by the driver (finite numbers, no negative unsigned);
// rgbd-synth (validation/, its own driver) makes the same checks.
const Refused kRefused[] = {
    {"rgbd-clean small.ply --consensus-ratio nan -o out.ply",
     "--consensus-ratio must be a finite number, got nan"},
    {"rgbd-clean small.ply --beta 0.5 -o out.ply", "--beta applies only with --density"},
    {"rgbd-clean small.ply --density --c-min 3 -o out.ply",
     "--c-min does not apply with --density"},
    {"rgbd-clean small.ply --radius-m 1 -o out.ply", "--radius-m applies only with --radius"},
    {"rgbd-info small.ply --seed -1", "--seed must be >= 0, got -1"},
    {"rgbd-cloud badcap --z-max 1e300 -o out.ply", "--z-max must be in [0, 100] m, got 1e300"},
    {"rgbd-align small.ply --max-prior-rotation-deg 1e300 -o out.ply",
     "--max-prior-rotation-deg must be in [0, 360] degrees"},
    {"rgbd-align small.ply --calibration-prior-deg 0 -o out.ply",
     "--calibration-prior-deg and --calibration-prior-mm must both be positive, or both 0"},
    {"rgbd-render small.ply --azimuth inf -o out.png", "--azimuth must be a finite number"},
    {"rgbd-render small.ply --scalar-min 0 -o out.png", "--scalar-min applies only with --scalar"},
    {"rgbd-eval small.ply --reference small.ply --baseline-depths 8 -o out.json",
     "--baseline-depths applies only with --baseline"},
    {"rgbd-capture --rig badcap/rig.json --voxel-mm 2 -o out_capture",
     "--voxel-mm applies only with --video"},
    {"rgbd-synth garbage.off --board-blur-px 1 -o out_capture",
     "--board-blur-px applies only with --target charuco"},
    {"rgbd-synth garbage.off --seed -1 -o out_capture", "--seed must be >= 0, got -1"},
    {"rgbd-mesh small.ply --no-carve-closure -o out.ply",
     "--no-carve-closure applies only with --watertight"},
    {"rgbd-reconstruct badcap --open --no-carve-closure -o out.ply",
     "--no-carve-closure does not apply with --open"},
    {"rgbd-reconstruct badcap --refine-colour -o out.ply",
     "--refine-colour applies only to a textured model (-o .obj or .glb)"},
};

}  // namespace

TEST(FailureContract, AbsurdValuesAndOptionsOfAnotherModeAreUsageErrors) {
    make_inputs();
    const std::set<std::string> before = entries();
    const std::regex kCaptured("(out|err)[0-9]+\\.txt");
    for (const Refused& c : kRefused) {
        SCOPED_TRACE(c.command);
        const Outcome r = run(std::string("$BIN/") + c.command);
        EXPECT_EQ(r.code, 2) << r.err;
        const std::string tool = std::string(c.command).substr(0, std::string(c.command).find(' '));
        const std::string first = r.err.substr(0, r.err.find('\n'));
        EXPECT_EQ(first.rfind(tool + ": error: " + c.message, 0), 0u) << r.err;
        EXPECT_TRUE(r.out.empty()) << r.out.substr(0, 200);
        for (const std::string& name : entries()) {
            if (before.count(name) || std::regex_match(name, kCaptured)) continue;
            ADD_FAILURE() << "left behind: " << name;
            fs::remove_all(temp_root() / name);
        }
    }
}
