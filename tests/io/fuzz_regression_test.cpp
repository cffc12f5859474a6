// Inputs found by the fuzz targets of validation/robustness/fuzz/ (issue 21) and by reading
// the code they pointed at, kept so the bugs stay fixed: each must give a clean InputError
// naming the input (never a crash, a hang or a huge allocation) in the normal suite.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>

#include "io/capture_folder.hpp"
#include "io/mesh_io.hpp"
#include "io/ply_stream.hpp"
#include "tests/support/input_error.hpp"
#include "toolkit/error.hpp"

namespace {

using rgbd::test::expect_input_error;

using namespace rgbd;

/// Reads every document of `bytes`; returns the error message ("" when none).
std::string read_stream(const std::string& bytes) {
    std::istringstream in(bytes);
    io::PlyStreamReader reader(in, "fuzz.ply");
    io::Document d;
    try {
        while (reader.next(d)) {
        }
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

/// Writes `bytes` to a file of that name in a scratch folder and reads it as a point cloud
/// (`mesh` = as a mesh); returns the error message ("" when none).
std::string read_file(const std::string& name, const std::string& bytes, bool mesh) {
    const auto dir = std::filesystem::temp_directory_path() / "rgbd_fuzz_regression_test";
    std::filesystem::create_directories(dir);
    const auto path = dir / name;
    std::ofstream(path, std::ios::binary) << bytes;
    try {
        if (mesh)
            io::read_mesh(path);
        else
            io::read_point_cloud(path);
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

}  // namespace

TEST(FuzzRegression, PlyElementWithoutPropertiesAndAHugeCountIsAnErrorNotAnEndlessLoop) {
    // The reader used to loop 2^64 times over rows of nothing. A hang guard, not a speed
    // check: the fixed reader answers in microseconds, the old one would run for centuries,
    // so the limit is set far above any machine's load (speed belongs in validation/performance).
    constexpr auto kHangGuard = std::chrono::seconds(60);
    for (const char* format : {"ascii", "binary_little_endian", "binary_big_endian"}) {
        SCOPED_TRACE(format);
        const auto t0 = std::chrono::steady_clock::now();
        const std::string err = read_stream(std::string("ply\nformat ") + format +
                                            " 1.0\nelement vertex 0\nproperty float x\n"
                                            "element junk 18446744073709551615\nend_header\n");
        EXPECT_NE(err.find("fuzz.ply"), std::string::npos) << err;
        EXPECT_NE(err.find("no properties"), std::string::npos) << err;
        EXPECT_LT(std::chrono::steady_clock::now() - t0, kHangGuard);
    }
}

TEST(FuzzRegression, PlyHugeCountWithWideRowsInAShortDocumentIsTruncatedNotAHugeAllocation) {
    // 200 double properties (1600-byte rows) and a list: the reader used to allocate
    // min(count, 2^24) rows up front, 27 GB for this 4 KB document.
    std::string header = "ply\nformat binary_little_endian 1.0\nelement vertex 99999999999\n";
    for (int i = 0; i < 200; ++i) header += "property double p" + std::to_string(i) + "\n";
    header += "property list uchar int idx\nend_header\n";
    const std::string err = read_stream(header + std::string(100, '\0'));
    EXPECT_NE(err.find("truncated"), std::string::npos) << err;
    std::string ascii = "ply\nformat ascii 1.0\nelement vertex 99999999999\n";
    for (int i = 0; i < 200; ++i) ascii += "property double p" + std::to_string(i) + "\n";
    const std::string err2 = read_stream(ascii + "end_header\n1 2 3\n");
    EXPECT_NE(err2.find("truncated"), std::string::npos) << err2;
}

TEST(FuzzRegression, PcdHeaderClaimingMorePointsThanTheFileHoldsIsTruncated) {
    // POINTS 2^62 with 12-byte rows: the reader allocated points * stride bytes (an overflow
    // to a small size, or an exabyte) before looking at the data.
    const std::string head =
        "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
        "WIDTH 4611686018427387904\nHEIGHT 1\nPOINTS 4611686018427387904\n";
    for (const char* data : {"ascii", "binary", "binary_compressed"}) {
        SCOPED_TRACE(data);
        const std::string err =
            read_file("huge.pcd", head + "DATA " + data + "\n" + std::string(64, '\1'), false);
        EXPECT_NE(err.find("huge.pcd"), std::string::npos) << err;
        EXPECT_FALSE(err.empty());
    }
    // A true count still reads.
    EXPECT_EQ(read_file("ok.pcd",
                        "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\n"
                        "POINTS 2\nDATA ascii\n0 0 1\n1 0 1\n",
                        false),
              "");
}

TEST(FuzzRegression, OffCountsWhoseSumOverflowsAreTruncatedNotAHugeReserve) {
    const std::string err =
        read_file("wrap.off", "OFF\n9223372036854775807 9223372036854775807 0\n0 0 0\n", true);
    EXPECT_NE(err.find("wrap.off"), std::string::npos) << err;
    EXPECT_NE(err.find("truncated"), std::string::npos) << err;
}

TEST(FuzzRegression, RedwoodIntrinsicSizeBeyond32BitsIsAnErrorNotWrappedAround) {
    // A Redwood folder with 8x6 images whose camera_intrinsic.json says width 2^32 + 8: the
    // reader took get<int>(), which wraps that around to 8, and accepted the file.
    namespace fs = std::filesystem;
    const fs::path root = fs::temp_directory_path() / "rgbd_fuzz_regression_test" / "redwood";
    fs::remove_all(root);
    fs::create_directories(root / "depth");
    fs::create_directories(root / "color");
    cv::imwrite((root / "depth" / "000000.png").string(), cv::Mat(6, 8, CV_16UC1, cv::Scalar(900)));
    cv::imwrite((root / "color" / "000000.png").string(), cv::Mat(6, 8, CV_8UC3, cv::Scalar(9)));
    const auto intrinsics = [&](const std::string& width) {
        std::ofstream(root / "camera_intrinsic.json")
            << R"({"width": )" << width
            << R"(, "height": 6, "intrinsic_matrix": [7, 0, 0, 0, 7, 0, 3.5, 2.5, 1]})";
    };
    intrinsics("8");
    const io::Capture ok = io::open_capture(root);
    EXPECT_EQ(ok.rig.sensors.at(0).depth.width, 8);
    EXPECT_NO_THROW(io::load_frame(ok, ok.rig.sensors.at(0).id, 0));
    for (const char* width : {"4294967304", "18446744073709551615", "-4294967288"}) {
        SCOPED_TRACE(width);
        intrinsics(width);
        expect_input_error([&] { io::open_capture(root); }, {"camera_intrinsic.json"});
    }
}

TEST(FuzzRegression, RigJsonWithANumberBeyondDoubleIsAnErrorNotAnEscapedException) {
    // Found by fuzz_capture_folder: nlohmann's parser reports a number too large for a double
    // as out_of_range, not parse_error, and read_rig caught only parse_error, so the exception
    // escaped every reader's contract (and ended rgbd-* tools with "internal error").
    namespace fs = std::filesystem;
    const fs::path root = fs::temp_directory_path() / "rgbd_fuzz_regression_test" / "bigrig";
    fs::remove_all(root);
    fs::create_directories(root);
    for (const char* text : {"19999999999999999929999E99999999999900000000000009632337040367573019",
                             R"({"format": "rgbd-capture", "version": 1e400})"}) {
        SCOPED_TRACE(text);
        std::ofstream(root / "rig.json") << text;
        expect_input_error([&] { io::open_capture(root); }, {"rig.json"});
    }
}
