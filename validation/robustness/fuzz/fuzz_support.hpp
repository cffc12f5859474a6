// Shared by the libFuzzer targets of validation/robustness/fuzz/ (issue 21): a scratch folder
// per process, writing the fuzz input to a file, and the reader contract every target checks.
// The contract: a reader given any bytes returns or throws rgbd::Error (InputError/IoError,
// naming the file); any other exception escapes and libFuzzer reports it as a crash, as it
// does for memory errors (ASan), undefined behaviour (UBSan), hangs and huge allocations.
#pragma once

#include <unistd.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "io/capture_folder.hpp"
#include "toolkit/error.hpp"

namespace rgbd::fuzz {

/// A folder of this process in memory (/dev/shm, a tmpfs, where there is one; else the
/// temporary directory), created on first use and removed when the process exits normally
/// (libFuzzer's -max_total_time): the file-based targets write and read it on every input,
/// so a disk would cost most of their time.
inline const std::filesystem::path& scratch() {
    struct Folder {
        std::filesystem::path path;
        Folder() {
            std::error_code ec;
            const std::filesystem::path shm = "/dev/shm";
            const auto base =
                std::filesystem::is_directory(shm, ec) && ::access("/dev/shm", W_OK) == 0
                    ? shm
                    : std::filesystem::temp_directory_path();
            path = base / ("rgbd-fuzz-" + std::to_string(::getpid()));
            std::filesystem::create_directories(path);
        }
        ~Folder() {
            std::error_code ec;
            std::filesystem::remove_all(path, ec);
        }
    };
    static const Folder folder;
    return folder.path;
}

/// The bytes of the file at `path` ("" when it cannot be read).
inline std::string slurp(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// Writes `size` bytes to `path` (replacing it).
inline void write_file(const std::filesystem::path& path, const std::uint8_t* data,
                       std::size_t size) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
}

inline void write_file(const std::filesystem::path& path, const std::string& text) {
    write_file(path, reinterpret_cast<const std::uint8_t*>(text.data()), text.size());
}

/// Runs `read`; rgbd::Error (the readers' documented failure) is a correct answer.
template <typename F>
void expect_clean(F&& read) {
    try {
        read();
    } catch (const rgbd::Error&) {
    }
}

/// Opens the capture folder at `root` and loads, of each sensor's n frames, the ones at the
/// positions `positions(n)` returns; each step is expect_clean.
template <typename Positions>
void open_and_load(const std::filesystem::path& root, Positions&& positions) {
    expect_clean([&] {
        const io::Capture capture = io::open_capture(root);
        for (const auto& entry : capture.frames)  // not a binding: clang 14 cannot capture one
            for (const std::size_t k : positions(entry.second.size()))
                expect_clean([&] { io::load_frame(capture, entry.first, k); });
    });
}

/// The one-sensor rig of the capture-folder seeds and target: 8x6 depth and colour images,
/// focal length 7 px, principal point at the centre.
inline io::Rig small_rig() {
    io::Rig rig;
    io::SensorSpec s;
    s.id = "k0";
    s.model = "kinect_v2";
    s.depth.width = s.color.width = 8;
    s.depth.height = s.color.height = 6;
    s.depth.fx = s.depth.fy = s.color.fx = s.color.fy = 7;
    s.depth.cx = s.color.cx = 3.5;
    s.depth.cy = s.color.cy = 2.5;
    rig.sensors.push_back(s);
    return rig;
}

/// Writes the capture folder of the capture-folder seeds and target at `root` (which must not
/// exist or be empty): sensor k0 of small_rig() with two frames 33 ms apart, each its own frame
/// set, of the 8x6 depth image `depth_m` (metres) and a uniform colour; the first frame with
/// the pose `first_pose` when given. Returns the files the target's selector byte 0-3 picks:
/// rig.json, k0/frames.csv, framesets.csv, the first depth image.
inline std::array<std::filesystem::path, 4> write_small_capture(
    const std::filesystem::path& root, const cv::Mat& depth_m,
    const std::optional<Pose>& first_pose = std::nullopt) {
    io::CaptureWriter writer(root, small_rig());
    const cv::Mat color(6, 8, CV_8UC3, cv::Scalar(10, 200, 30));
    writer.add_frame("k0", 0, 1000, depth_m, color, first_pose);
    writer.add_frame("k0", 1, 34'000'000, depth_m, color);
    writer.add_frameset({0, 1000, 0, {0}});
    writer.add_frameset({1, 34'000'000, 0, {1}});
    return {root / "rig.json", root / "k0" / "frames.csv", root / "framesets.csv",
            writer.depth_file("k0", 0)};
}

}  // namespace rgbd::fuzz
