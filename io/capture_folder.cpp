#include "io/capture_folder.hpp"

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

#include "io/internal/atomic_file.hpp"
#include "io/internal/capture_common.hpp"
#include "io/internal/depth_png.hpp"
#include "toolkit/error.hpp"

namespace rgbd::io {

namespace {

using namespace internal;

PinholeIntrinsics parse_intrinsics(const json& j, const RigContext& ctx, const char* name) {
    const RigContext c{ctx.path, ctx.where + ": " + name};
    if (!j.is_object()) c.fail("must be an object");
    PinholeIntrinsics k;
    const auto size = [&](const char* key) {
        const json& v = c.at(j, key);
        if (!v.is_number_integer()) c.fail(std::string(key) + " must be an integer");
        return v.get<std::int64_t>();
    };
    const auto w = size("width"), h = size("height");
    if (w <= 0 || h <= 0 || w > 100000 || h > 100000) c.fail("width and height must be positive");
    k.width = static_cast<int>(w);
    k.height = static_cast<int>(h);
    k.fx = c.number(c.at(j, "fx"), "fx");
    k.fy = c.number(c.at(j, "fy"), "fy");
    k.cx = c.number(c.at(j, "cx"), "cx");
    k.cy = c.number(c.at(j, "cy"), "cy");
    if (j.contains("distortion")) {
        const json& d = j.at("distortion");
        k.distortion.model = c.string(c.at(d, "model"), "distortion.model");
        if (d.contains("coeffs")) {
            if (!d.at("coeffs").is_array()) c.fail("distortion.coeffs must be an array");
            for (const json& v : d.at("coeffs"))
                k.distortion.coeffs.push_back(c.number(v, "distortion coefficient"));
        }
    }
    try {
        k.check();
    } catch (const InputError& e) {
        c.fail(e.what());
    }
    return k;
}

json intrinsics_json(const PinholeIntrinsics& k) {
    return {{"width", k.width},
            {"height", k.height},
            {"fx", k.fx},
            {"fy", k.fy},
            {"cx", k.cx},
            {"cy", k.cy},
            {"distortion", {{"model", k.distortion.model}, {"coeffs", k.distortion.coeffs}}}};
}

Pose parse_matrix(const json& j, const RigContext& ctx, const char* name) {
    const RigContext c{ctx.path, ctx.where + ": " + name};
    if (!j.is_array() || j.size() != 4) c.fail("must be a 4x4 array (4 rows of 4 numbers)");
    std::array<double, 16> m{};
    for (std::size_t r = 0; r < 4; ++r) {
        if (!j[r].is_array() || j[r].size() != 4)
            c.fail("must be a 4x4 array (4 rows of 4 numbers)");
        for (std::size_t col = 0; col < 4; ++col) m[r * 4 + col] = c.number(j[r][col], "entry");
    }
    try {
        pose_from_4x4(m);
    } catch (const InputError& e) {
        c.fail(std::string("not a rigid transform: ") + e.what());
    }
    return exact_pose({m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8], m[9], m[10], m[11]});
}

json matrix_json(const Pose& p) {
    json rows = json::array();
    for (int r = 0; r < 4; ++r) {
        json row = json::array();
        for (int c = 0; c < 4; ++c) row.push_back(p.matrix()(r, c));
        rows.push_back(row);
    }
    return rows;
}

/// Keeps the entries of an object other than `known`.
json without(const json& obj, std::initializer_list<const char*> known) {
    json out = json::object();
    for (auto it = obj.begin(); it != obj.end(); ++it) {
        bool is_known = false;
        for (const char* k : known) is_known = is_known || it.key() == k;
        if (!is_known) out[it.key()] = it.value();
    }
    return out;
}

SensorSpec parse_sensor(const json& j, const fs::path& path, std::size_t number) {
    RigContext c{path, "sensors[" + std::to_string(number) + "]"};
    if (!j.is_object()) c.fail("must be an object");
    SensorSpec s;
    s.id = c.string(c.at(j, "id"), "id");
    if (s.id.empty() || s.id.find_first_of("/\\,\n") != std::string::npos || s.id == "." ||
        s.id == "..")
        c.fail("id '" + s.id + "' is empty or contains '/', '\\' or ','");
    c.where = "sensor '" + s.id + "'";
    if (j.contains("model")) s.model = c.string(j.at("model"), "model");
    s.depth = parse_intrinsics(c.at(j, "depth"), c, "depth");
    s.color = j.contains("color") ? parse_intrinsics(j.at("color"), c, "color") : s.depth;
    s.depth_scale = c.number(c.at(j, "depth_scale"), "depth_scale");
    if (!(s.depth_scale > 0)) c.fail("depth_scale must be positive");
    if (j.contains("range_m")) {
        const json& r = j.at("range_m");
        if (!r.is_array() || r.size() != 2) c.fail("range_m must be [min, max]");
        s.range_min_m = c.number(r[0], "range_m[0]");
        s.range_max_m = c.number(r[1], "range_m[1]");
        if (s.range_min_m < 0 || !(s.range_min_m < s.range_max_m))
            c.fail("range_m must satisfy 0 <= min < max");
    }
    if (j.contains("color_from_depth"))
        s.color_from_depth = parse_matrix(j.at("color_from_depth"), c, "color_from_depth");
    s.has_world_from_depth = j.contains("world_from_depth");
    if (s.has_world_from_depth)
        s.world_from_depth = parse_matrix(j.at("world_from_depth"), c, "world_from_depth");
    s.extra = without(j, {"id", "model", "depth", "color", "depth_scale", "range_m",
                          "color_from_depth", "world_from_depth", "noise", "clock"});
    if (j.contains("noise")) {
        const json& n = j.at("noise");
        if (!n.is_object()) c.fail("noise must be an object");
        if (n.contains("model")) s.noise_model = c.string(n.at("model"), "noise.model");
        const json rest = without(n, {"model"});
        if (!rest.empty()) s.extra["noise"] = rest;
    }
    if (j.contains("clock")) {
        const json& k = j.at("clock");
        if (!k.is_object()) c.fail("clock must be an object");
        if (k.contains("offset_ns")) {
            if (!k.at("offset_ns").is_number_integer())
                c.fail("clock.offset_ns must be an integer");
            s.clock_offset_ns = k.at("offset_ns").get<std::int64_t>();
        }
        const json rest = without(k, {"offset_ns"});
        if (!rest.empty()) s.extra["clock"] = rest;
    }
    return s;
}

json sensor_json(const SensorSpec& s) {
    json j = s.extra.is_object() ? s.extra : json::object();
    j["id"] = s.id;
    j["model"] = s.model;
    j["depth"] = intrinsics_json(s.depth);
    j["color"] = intrinsics_json(s.color);
    j["depth_scale"] = s.depth_scale;
    if (s.range_min_m != 0 || s.range_max_m != 0) j["range_m"] = {s.range_min_m, s.range_max_m};
    j["color_from_depth"] = matrix_json(s.color_from_depth);
    if (s.has_world_from_depth) j["world_from_depth"] = matrix_json(s.world_from_depth);
    if (!s.noise_model.empty()) {
        if (!j["noise"].is_object()) j["noise"] = json::object();
        j["noise"]["model"] = s.noise_model;
    }
    if (!j["clock"].is_object()) j["clock"] = json::object();
    j["clock"]["offset_ns"] = s.clock_offset_ns;
    return j;
}

void check_rig(const Rig& rig, const fs::path& path) {
    if (rig.sensors.empty()) fail(path, "rig has no sensors");
    std::set<std::string> ids;
    for (const SensorSpec& s : rig.sensors)
        if (!ids.insert(s.id).second) fail(path, "duplicate sensor id '" + s.id + "'");
}

// ------------------------------------------------------------------------------ csv files

std::vector<FrameRecord> read_frames_csv(const fs::path& path) {
    std::istringstream in(read_text(path));
    std::string line;
    if (!std::getline(in, line)) fail(path, "empty file (no header)");
    const auto header = split_csv(line);
    const std::vector<std::string> base = {"index", "time_ns", "depth", "color"};
    bool poses = false;
    if (header.size() == 16) {
        for (std::size_t k = 0; k < 12; ++k)
            if (header[4 + k] != kPoseColumns[k])
                fail(path, "header column " + std::to_string(5 + k) + " is '" + header[4 + k] +
                               "', expected '" + kPoseColumns[k] + "'");
        poses = true;
    } else if (header.size() != 4) {
        fail(path, "header must be index,time_ns,depth,color[,r00,...,t2]");
    }
    if (!std::equal(base.begin(), base.end(), header.begin()))
        fail(path, "header must start with index,time_ns,depth,color");
    std::vector<FrameRecord> frames;
    for_each_csv_row(
        in, path, header.size(), [&](const std::vector<std::string>& cells, const auto& bad) {
            FrameRecord r;
            if (!to_int64(cells[0], r.index)) bad("bad index '" + cells[0] + "'");
            if (!to_int64(cells[1], r.time_ns)) bad("bad time_ns '" + cells[1] + "'");
            r.depth = cells[2];
            r.color = cells[3];
            if (r.depth.empty()) bad("empty depth path");
            if (poses) {
                const bool empty = std::all_of(cells.begin() + 4, cells.end(),
                                               [](const std::string& c) { return c.empty(); });
                if (!empty) {
                    std::array<double, 12> m{};
                    for (std::size_t k = 0; k < 12; ++k)
                        if (!to_double(cells[4 + k], m[k]) || !std::isfinite(m[k]))
                            bad("bad pose value '" + cells[4 + k] + "'");
                    try {
                        r.world_from_depth = exact_pose(m);
                    } catch (const InputError& e) {
                        bad(std::string("pose is not rigid: ") + e.what());
                    }
                }
            }
            frames.push_back(std::move(r));
        });
    return frames;
}

std::vector<FrameSet> read_framesets_csv(const fs::path& path, const Rig& rig) {
    std::istringstream in(read_text(path));
    std::string line;
    if (!std::getline(in, line)) fail(path, "empty file (no header)");
    const auto header = split_csv(line);
    if (header.size() < 3 || header[0] != "set" || header[1] != "time_ns" ||
        header[2] != "spread_ns")
        fail(path, "header must be set,time_ns,spread_ns,<sensor ids>");
    std::vector<std::size_t> column_of_sensor(rig.sensors.size(), 0);  // 0 = absent
    for (std::size_t c = 3; c < header.size(); ++c) {
        std::size_t s = 0;
        while (s < rig.sensors.size() && rig.sensors[s].id != header[c]) ++s;
        if (s == rig.sensors.size())
            fail(path, "column '" + header[c] + "' is not a sensor of the rig");
        if (column_of_sensor[s] != 0) fail(path, "sensor '" + header[c] + "' appears twice");
        column_of_sensor[s] = c;
    }
    std::vector<FrameSet> sets;
    for_each_csv_row(
        in, path, header.size(), [&](const std::vector<std::string>& cells, const auto& bad) {
            FrameSet set;
            if (!to_int64(cells[0], set.set) || !to_int64(cells[1], set.time_ns) ||
                !to_int64(cells[2], set.spread_ns))
                bad("bad number");
            for (std::size_t s = 0; s < rig.sensors.size(); ++s) {
                std::int64_t f = -1;
                if (column_of_sensor[s] != 0 && !to_int64(cells[column_of_sensor[s]], f))
                    bad("bad frame index '" + cells[column_of_sensor[s]] + "'");
                set.frames.push_back(f);
            }
            sets.push_back(std::move(set));
        });
    return sets;
}

// Appends one line; on failure (disk full) the file is cut back to its previous length so it

void check_size(const std::string& file, const cv::Mat& image, const PinholeIntrinsics& k,
                const char* what) {
    if (image.cols != k.width || image.rows != k.height)
        fail(file, std::string(what) + " image is " + std::to_string(image.cols) + "x" +
                       std::to_string(image.rows) + " but the rig declares " +
                       std::to_string(k.width) + "x" + std::to_string(k.height));
}

}  // namespace

// ---------------------------------------------------------------------------------------

std::string to_string(DepthEncoding encoding) {
    switch (encoding) {
        case DepthEncoding::kPlain:
            return "plain";
        case DepthEncoding::kApcRotated3:
            return "apc_rotated3";
    }
    return "unknown";
}

void decode_depth(cv::Mat& stored, DepthEncoding encoding) {
    if (encoding == DepthEncoding::kPlain) return;
    if (stored.type() != CV_16UC1) throw InputError("decode_depth: depth must be CV_16UC1");
    for (int y = 0; y < stored.rows; ++y) {
        std::uint16_t* row = stored.ptr<std::uint16_t>(y);
        for (int x = 0; x < stored.cols; ++x)  // rotate left by 13 = undo rotate right by 3
            row[x] = static_cast<std::uint16_t>((row[x] << 13) | (row[x] >> 3));
    }
}

const SensorSpec& Rig::sensor(const std::string& id) const {
    for (const SensorSpec& s : sensors)
        if (s.id == id) return s;
    throw InputError("no sensor '" + id + "' in the rig");
}

Rig read_rig(const fs::path& path) {
    json j;
    try {
        j = json::parse(read_text(path));
    } catch (const json::exception& e) {  // parse_error, and out_of_range for 1e99999
        fail(path, std::string("not valid JSON: ") + e.what());
    }
    const RigContext c{path, ""};
    if (!j.is_object()) c.fail("top level must be a JSON object");
    if (c.string(c.at(j, "format"), "format") != "rgbd-capture")
        c.fail("format must be \"rgbd-capture\"");
    const json& version = c.at(j, "version");
    if (!version.is_number_integer() || version.get<int>() != 1)
        c.fail("unsupported version " + version.dump() + " (this reader knows version 1)");
    if (c.string(c.at(j, "units"), "units") != "m") c.fail("units must be \"m\"");
    const json& sensors = c.at(j, "sensors");
    if (!sensors.is_array()) c.fail("sensors must be an array");
    Rig rig;
    for (std::size_t i = 0; i < sensors.size(); ++i)
        rig.sensors.push_back(parse_sensor(sensors[i], path, i));
    check_rig(rig, path);
    rig.extra = without(j, {"format", "version", "units", "sensors"});
    return rig;
}

void write_rig(const fs::path& path, const Rig& rig) {
    check_rig(rig, path);
    for (const SensorSpec& s : rig.sensors) {
        try {
            s.depth.check();
            s.color.check();
        } catch (const InputError& e) {
            fail(path, "sensor '" + s.id + "': " + e.what());
        }
        if (!(s.depth_scale > 0)) fail(path, "sensor '" + s.id + "': depth_scale must be positive");
    }
    json j = rig.extra.is_object() ? rig.extra : json::object();
    j["format"] = "rgbd-capture";
    j["version"] = 1;
    j["units"] = "m";
    j["sensors"] = json::array();
    for (const SensorSpec& s : rig.sensors) j["sensors"].push_back(sensor_json(s));
    write_text_atomic(path, j.dump(2) + "\n");
}

std::optional<std::size_t> Capture::find_frame(const std::string& sensor_id,
                                               std::int64_t index) const {
    const auto it = frames.find(sensor_id);
    if (it == frames.end()) return std::nullopt;
    const auto& list = it->second;
    if (index >= 0 && static_cast<std::size_t>(index) < list.size() &&
        list[static_cast<std::size_t>(index)].index == index)
        return static_cast<std::size_t>(index);
    for (std::size_t k = 0; k < list.size(); ++k)
        if (list[k].index == index) return k;
    return std::nullopt;
}

Capture open_capture(const fs::path& root) {
    if (!has_dir(root)) fail(root, "no such folder");
    if (has_file(root / "rig.json")) {
        Capture cap;
        cap.root = root;
        cap.layout = "rgbd-capture";
        cap.rig = read_rig(root / "rig.json");
        for (const SensorSpec& s : cap.rig.sensors) {
            const fs::path csv = root / s.id / "frames.csv";
            cap.frames[s.id] = has_file(csv) ? read_frames_csv(csv) : std::vector<FrameRecord>{};
        }
        if (has_file(root / "framesets.csv"))
            cap.framesets = read_framesets_csv(root / "framesets.csv", cap.rig);
        return cap;
    }
    if (has_file(root / "cam.info.txt")) {
        static const std::regex kApcDepth(R"(frame-\d+\.depth\.png)");
        std::vector<fs::path> depth;
        for (const fs::path& f : list_files(root))
            if (std::regex_match(f.filename().string(), kApcDepth)) depth.push_back(f);
        if (!depth.empty()) return open_apc(root, depth);
    }
    std::vector<fs::path> xmls;
    static const std::regex kCameraXml(R"(\d+_camera\.xml)");
    for (const fs::path& f : list_files(root))
        if (std::regex_match(f.filename().string(), kCameraXml)) xmls.push_back(f);
    if (!xmls.empty()) return open_uva(root, xmls);
    if (has_file(root / "depth.txt") || has_file(root / "TUM_depth.png")) return open_tum(root);
    if (const auto folder = redwood_folder(root)) return open_redwood(root, *folder);
    fail(root,
         "not a capture folder (no rig.json, no TUM depth.txt or TUM_depth.png, no "
         "color/ + depth/ folders, no NNN_camera.xml frames, no APC cam.info.txt + "
         "frame-NNNNNN.depth.png)");
}

RgbdFrame frame_from_stored(const SensorSpec& s, const cv::Mat& raw, const cv::Mat& color_bgr,
                            const std::string& what) {
    if (raw.type() != CV_16UC1) fail(what, "depth image is not 16-bit single-channel");
    check_size(what, raw, s.depth, "depth");
    RgbdFrame frame;
    frame.depth.create(raw.rows, raw.cols, CV_32FC1);
    const float inv = static_cast<float>(1.0 / s.depth_scale);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (int y = 0; y < raw.rows; ++y) {
        const std::uint16_t* in = raw.ptr<std::uint16_t>(y);
        float* out = frame.depth.ptr<float>(y);
        for (int x = 0; x < raw.cols; ++x) out[x] = in[x] == 0 ? nan : in[x] * inv;
    }
    if (!color_bgr.empty()) {
        if (color_bgr.type() != CV_8UC3) fail(what, "colour image is not 8-bit BGR");
        check_size(what, color_bgr, s.color, "colour");
        frame.color = color_bgr;
    }
    frame.depth_intrinsics = s.depth;
    frame.color_intrinsics = s.color;
    frame.color_from_depth = s.color_from_depth;
    frame.world_from_sensor = s.world_from_depth;
    frame.has_pose = s.has_world_from_depth;
    frame.sensor_id = s.id;
    frame.range_min_m = static_cast<float>(s.range_min_m);
    frame.range_max_m = static_cast<float>(s.range_max_m);
    frame.noise_model = s.noise_model;
    frame.sensor_model = s.model;
    return frame;
}

RgbdFrame load_frame(const Capture& capture, const std::string& sensor_id, std::size_t position) {
    const SensorSpec& s = capture.rig.sensor(sensor_id);
    const auto it = capture.frames.find(sensor_id);
    if (it == capture.frames.end() || position >= it->second.size())
        throw InputError(capture.root.string() + ": sensor '" + sensor_id +
                         "' has no frame at position " + std::to_string(position));
    const FrameRecord& r = it->second[position];
    const auto resolve = [&](const std::string& p) {
        const fs::path path(p);
        return (path.is_absolute() ? path : capture.root / sensor_id / path).string();
    };
    const std::string depth_file = resolve(r.depth);
    cv::Mat raw = read_capture_image(depth_file, ImageMode::kUnchanged, "depth");
    if (s.depth_encoding != DepthEncoding::kPlain) {
        if (raw.type() != CV_16UC1) fail(depth_file, "depth image is not 16-bit single-channel");
        decode_depth(raw, s.depth_encoding);
    }
    cv::Mat color;
    std::string color_file;
    if (!r.color.empty()) {
        color_file = resolve(r.color);
        color = read_capture_image(color_file, ImageMode::kColor, "colour");
        check_size(color_file, color, s.color, "colour");
    }
    RgbdFrame frame = frame_from_stored(s, raw, color, depth_file);
    if (!r.mask.empty()) {
        const std::string mask_file = resolve(r.mask);
        const cv::Mat mask = read_capture_image(mask_file, ImageMode::kGrey, "mask");
        check_size(mask_file, mask, s.depth, "mask");
        cv::compare(mask, 128, frame.mask, cv::CMP_GE);  // JPEG edges are soft: threshold
    }
    if (r.world_from_depth) {
        frame.world_from_sensor = *r.world_from_depth;
        frame.has_pose = true;
    }
    frame.sensor_id = sensor_id;
    frame.frame_index = r.index;
    frame.timestamp_ns = r.time_ns - s.clock_offset_ns;
    frame.source = depth_file;
    return frame;
}

// ---------------------------------------------------------------------------------------

}  // namespace rgbd::io
