// Helpers shared by the capture folder reader (io/capture_folder.cpp), the foreign layouts
// (io/capture_foreign.cpp: UvA, TUM RGB-D, Open3D/Redwood, APC) and the writer
// (io/capture_writer.cpp): text and csv parsing, the rig.json error context, file checks.
// See also: io/capture_folder.hpp for the folder format.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <istream>
#include <optional>
#include <string>
#include <vector>

#include "io/capture_folder.hpp"
#include "io/image_codec.hpp"
#include "io/internal/file_text.hpp"
#include "toolkit/error.hpp"

namespace rgbd::io::internal {

namespace fs = std::filesystem;
using nlohmann::json;

/// The 12 optional pose columns of frames.csv (row-major 3x4 world_from_depth).
inline constexpr const char* kPoseColumns[12] = {"r00", "r01", "r02", "t0",  "r10", "r11",
                                                 "r12", "t1",  "r20", "r21", "r22", "t2"};

/// A capture's PNG or JPEG image (io/image_codec.hpp); InputError "FILE: missing WHAT image"
/// or "FILE: cannot decode WHAT image: why".
cv::Mat read_capture_image(const std::string& file, ImageMode mode, const char* what);

/// The whole file as bytes; InputError when it is not a regular file, IoError when unreadable.
std::string read_text(const fs::path& path);
/// `s` without leading and trailing blanks (space, tab, CR, LF).
std::string trim(const std::string& s);
/// The trimmed cells of one comma-separated line (no quoting).
std::vector<std::string> split_csv(const std::string& line);
/// The blank-separated words of a line.
std::vector<std::string> split_ws(const std::string& line);
/// Whole-string integer / double parses (a leading '+' is allowed); false on any junk.
bool to_int64(const std::string& s, std::int64_t& v);
bool to_double(const std::string& s, double& v);
/// A pose with exactly the given numbers, after checking that they form a rigid transform.
Pose exact_pose(const std::array<double, 12>& m);
/// Appends one line; on failure (disk full) the file is cut back to its previous length so it
/// never ends in a partial line.
void append_line(const fs::path& path, const std::string& line);
/// 640x480, f = 525 px: the Kinect v1 defaults of layouts without intrinsics.
PinholeIntrinsics default_intrinsics(double cx, double cy);
std::string absolute_path(const fs::path& p);
/// Regular files in `dir`, sorted by name (empty when `dir` cannot be read).
std::vector<fs::path> list_files(const fs::path& dir);
bool has_file(const fs::path& p);
bool has_dir(const fs::path& p);

/// fails naming the file and the line. Rows must have `columns` cells.
template <typename Row>
void for_each_csv_row(std::istream& in, const fs::path& path, std::size_t columns, Row&& row) {
    std::string line;
    std::size_t number = 1;
    while (std::getline(in, line)) {
        ++number;
        if (trim(line).empty()) continue;
        const auto cells = split_csv(line);
        const auto bad = [&](const std::string& why) {
            fail(path, "line " + std::to_string(number) + ": " + why);
        };
        if (cells.size() != columns)
            bad("expected " + std::to_string(columns) + " columns, got " +
                std::to_string(cells.size()));
        row(cells, bad);
    }
}

// ------------------------------------------------------------------------------ rig.json

/// Context for rig.json errors: "FILE: sensor 'ID': key: problem".
struct RigContext {
    const fs::path& path;
    std::string where;
    [[noreturn]] void fail(const std::string& problem) const {
        internal::fail(path, where.empty() ? problem : where + ": " + problem);
    }
    const json& at(const json& obj, const char* key) const {
        if (!obj.is_object() || !obj.contains(key)) fail(std::string("missing key '") + key + "'");
        return obj.at(key);
    }
    double number(const json& v, const std::string& what) const {
        if (!v.is_number()) fail(what + " must be a number");
        const double d = v.get<double>();
        if (!std::isfinite(d)) fail(what + " must be finite");
        return d;
    }
    std::string string(const json& v, const std::string& what) const {
        if (!v.is_string()) fail(what + " must be a string");
        return v.get<std::string>();
    }
};

// Foreign layouts (io/capture_foreign.cpp), opened by open_capture.
/// The "frames with OpenCV camera xml" layout (shared/data/multiview/uva_cv2_person_kinect1).
Capture open_uva(const fs::path& root, const std::vector<fs::path>& xmls);
/// The TUM RGB-D layout (rgb.txt, depth.txt, optional groundtruth.txt).
Capture open_tum(const fs::path& root);
/// The Open3D/Redwood folder holding color/ and depth/ below `root`, if any.
std::optional<fs::path> redwood_folder(const fs::path& root);
/// The Open3D/Redwood layout (color/, depth/, optional intrinsic json and .log trajectory).
Capture open_redwood(const fs::path& root, const fs::path& folder);
/// The APC vision toolbox scene layout: cam.info.txt and the `depth` images
/// frame-NNNNNN.depth.png (with frame-NNNNNN.color.png) in `root`.
Capture open_apc(const fs::path& root, const std::vector<fs::path>& depth);

}  // namespace rgbd::io::internal
