// CaptureWriter and the atomic image/bytes/text writers. See io/capture_folder.hpp.
#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <opencv2/core/persistence.hpp>
#include <regex>
#include <set>
#include <sstream>

#include "io/capture_folder.hpp"
#include "io/image_codec.hpp"
#include "io/internal/atomic_file.hpp"
#include "io/internal/capture_common.hpp"
#include "io/internal/depth_png.hpp"
#include "io/internal/text.hpp"
#include "toolkit/error.hpp"

namespace rgbd::io {

namespace {

using namespace internal;

std::string frame_name(std::int64_t index) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%06lld", static_cast<long long>(index));
    return buf;
}

/// InputError when the `what` image ("depth", "colour") of the sensor is not the size that the
/// rig declares for it.
void check_declared_size(const cv::Mat& image, const PinholeIntrinsics& declared,
                         const std::string& sensor_id, const std::string& what) {
    if (image.cols != declared.width || image.rows != declared.height)
        throw InputError("add_frame: sensor '" + sensor_id + "': " + what + " is " +
                         std::to_string(image.cols) + "x" + std::to_string(image.rows) +
                         " but the rig declares " + std::to_string(declared.width) + "x" +
                         std::to_string(declared.height));
}

}  // namespace

CaptureWriter::CaptureWriter(const fs::path& root, const Rig& rig) : root_(root), rig_(rig) {
    std::error_code ec;
    if (fs::exists(root, ec)) {
        if (!fs::is_directory(root, ec))
            throw IoError(root.string() + ": exists and is not a folder");
        if (!fs::is_empty(root, ec))
            throw IoError(root.string() + ": folder exists and is not empty");
    } else if (!fs::create_directories(root, ec) || ec) {
        throw IoError(root.string() + ": cannot create folder: " + ec.message());
    }
    write_rig(root / "rig.json", rig_);
}

CaptureWriter::~CaptureWriter() = default;

void CaptureWriter::add_frame(const std::string& sensor_id, std::int64_t index,
                              std::int64_t time_ns, const cv::Mat& depth_m,
                              const cv::Mat& color_bgr,
                              const std::optional<Pose>& world_from_depth) {
    const SensorSpec& s = rig_.sensor(sensor_id);
    const fs::path dir = root_ / sensor_id;
    if (depth_m.type() != CV_32FC1) throw InputError("add_frame: depth must be CV_32FC1 metres");
    check_declared_size(depth_m, s.depth, sensor_id, "depth");
    if (!color_bgr.empty()) {
        if (color_bgr.type() != CV_8UC3) throw InputError("add_frame: colour must be CV_8UC3 BGR");
        check_declared_size(color_bgr, s.color, sensor_id, "colour");
    }
    std::error_code ec;
    fs::create_directories(dir / "depth", ec);
    if (!color_bgr.empty()) fs::create_directories(dir / "color", ec);

    cv::Mat raw(depth_m.rows, depth_m.cols, CV_16UC1);
    for (int y = 0; y < depth_m.rows; ++y) {
        const float* in = depth_m.ptr<float>(y);
        std::uint16_t* out = raw.ptr<std::uint16_t>(y);
        for (int x = 0; x < depth_m.cols; ++x) {
            const double v = std::round(static_cast<double>(in[x]) * s.depth_scale);
            out[x] = std::isfinite(v) && v > 0 && v <= 65535 ? static_cast<std::uint16_t>(v) : 0;
        }
    }
    const std::string name = frame_name(index);
    const std::string depth_rel = "depth/" + name + ".png";
    write_image_atomic(dir / depth_rel, raw);
    std::string color_rel;
    if (!color_bgr.empty()) {
        color_rel = "color/" + name + ".jpg";
        write_image_atomic(dir / color_rel, color_bgr, 95);
    }

    const fs::path csv = dir / "frames.csv";
    bool posed = false;
    if (!has_file(csv)) {
        posed = world_from_depth.has_value();
        std::string header = "index,time_ns,depth,color";
        if (posed)
            for (const char* c : kPoseColumns) header += std::string(",") + c;
        append_line(csv, header);
    } else {
        std::ifstream in(csv);
        std::string header;
        std::getline(in, header);
        posed = split_csv(header).size() == 16;
    }
    if (world_from_depth && !posed)
        throw InputError("add_frame: sensor '" + sensor_id +
                         "': a frame with a pose after frames without (frames.csv has no pose "
                         "columns)");
    std::string line =
        std::to_string(index) + "," + std::to_string(time_ns) + "," + depth_rel + "," + color_rel;
    if (posed) {
        if (world_from_depth) {
            for (double v : pose_to_3x4(*world_from_depth)) line += "," + internal::format_exact(v);
        } else {
            line += std::string(12, ',');
        }
    }
    append_line(csv, line);
}

void CaptureWriter::add_encoded_frame(const std::string& sensor_id, std::int64_t index,
                                      std::int64_t time_ns, const cv::Mat& depth_raw,
                                      const std::vector<std::uint8_t>& color_jpeg,
                                      int png_compression) {
    const SensorSpec& s = rig_.sensor(sensor_id);
    if (depth_raw.type() != CV_16UC1)
        throw InputError("add_encoded_frame: depth must be CV_16UC1 (depth_scale units)");
    if (depth_raw.cols != s.depth.width || depth_raw.rows != s.depth.height)
        throw InputError("add_encoded_frame: sensor '" + sensor_id + "': depth is " +
                         std::to_string(depth_raw.cols) + "x" + std::to_string(depth_raw.rows) +
                         " but the rig declares " + std::to_string(s.depth.width) + "x" +
                         std::to_string(s.depth.height));
    const fs::path dir = root_ / sensor_id;
    std::error_code ec;
    fs::create_directories(dir / "depth", ec);
    if (!color_jpeg.empty()) fs::create_directories(dir / "color", ec);
    const std::string name = frame_name(index);
    const std::string depth_rel = "depth/" + name + ".png";
    thread_local std::vector<std::uint8_t> png;  // reused between frames
    internal::encode_depth_png(depth_raw, png_compression, png);
    write_bytes_atomic(dir / depth_rel, png.data(), png.size());
    std::string color_rel;
    if (!color_jpeg.empty()) {
        color_rel = "color/" + name + ".jpg";
        write_bytes_atomic(dir / color_rel, color_jpeg.data(), color_jpeg.size());
    }
    const fs::path csv = dir / "frames.csv";
    if (!has_file(csv)) append_line(csv, "index,time_ns,depth,color");
    append_line(csv, std::to_string(index) + "," + std::to_string(time_ns) + "," + depth_rel + "," +
                         color_rel);
}

fs::path CaptureWriter::depth_file(const std::string& sensor_id, std::int64_t index) const {
    return root_ / sensor_id / ("depth/" + frame_name(index) + ".png");
}

void CaptureWriter::add_frameset(const FrameSet& set) {
    if (set.frames.size() != rig_.sensors.size())
        throw InputError("add_frameset: " + std::to_string(set.frames.size()) +
                         " frame indices for " + std::to_string(rig_.sensors.size()) + " sensors");
    const fs::path csv = root_ / "framesets.csv";
    if (!framesets_header_written_) {
        std::string header = "set,time_ns,spread_ns";
        for (const SensorSpec& s : rig_.sensors) header += "," + s.id;
        append_line(csv, header);
        framesets_header_written_ = true;
    }
    std::string line = std::to_string(set.set) + "," + std::to_string(set.time_ns) + "," +
                       std::to_string(set.spread_ns);
    for (std::int64_t f : set.frames) line += "," + std::to_string(f);
    append_line(csv, line);
}

void write_image_atomic(const fs::path& path, const cv::Mat& image, int level_or_quality) {
    if (image.empty()) throw InputError(path.string() + ": empty image, nothing written");
    std::vector<std::uint8_t> bytes;
    try {
        bytes = encode_image(path.string(), image, level_or_quality);
    } catch (const Error& e) {
        throw IoError(path.string() + ": cannot encode image: " + e.what());
    }
    internal::write_file_atomic(path, [&](std::ostream& out) {
        out.write(reinterpret_cast<const char*>(bytes.data()),
                  static_cast<std::streamsize>(bytes.size()));
    });
}

void write_bytes_atomic(const fs::path& path, const std::uint8_t* data, std::size_t size) {
    internal::write_file_atomic(path, [&](std::ostream& out) {
        out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    });
}

void write_text_atomic(const fs::path& path, const std::string& text) {
    internal::write_file_atomic(path, [&](std::ostream& out) {
        out.write(text.data(), static_cast<std::streamsize>(text.size()));
    });
}

}  // namespace rgbd::io
