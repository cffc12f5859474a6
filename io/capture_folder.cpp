#include "io/capture_folder.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <opencv2/core/persistence.hpp>
#include <opencv2/imgcodecs.hpp>
#include <regex>
#include <set>
#include <sstream>

#include "io/internal/atomic_file.hpp"
#include "io/internal/depth_png.hpp"
#include "toolkit/error.hpp"

namespace rgbd::io {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr std::int64_t kFramePeriodNs = 33'333'333;  // 30 fps, for layouts without timestamps

[[noreturn]] void fail(const fs::path& path, const std::string& problem) {
    throw InputError(path.string() + ": " + problem);
}

std::string read_text(const fs::path& path) {
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) fail(path, "no such file");
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(path.string() + ": cannot open for reading");
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

std::string trim(const std::string& s) {
    const auto b = s.find_first_not_of(" \t\r\n");
    if (b == std::string::npos) return {};
    return s.substr(b, s.find_last_not_of(" \t\r\n") - b + 1);
}

std::vector<std::string> split_csv(const std::string& line) {
    std::vector<std::string> out;
    std::string cell;
    for (char c : line) {
        if (c == ',') {
            out.push_back(trim(cell));
            cell.clear();
        } else {
            cell.push_back(c);
        }
    }
    out.push_back(trim(cell));
    return out;
}

/// Calls row(cells, bad) for every non-blank line after the header of a csv file; `bad(why)`
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

std::vector<std::string> split_ws(const std::string& line) {
    std::istringstream s(line);
    std::vector<std::string> out;
    std::string t;
    while (s >> t) out.push_back(t);
    return out;
}

bool to_int64(const std::string& s, std::int64_t& v) {
    const char* b = s.data();
    if (!s.empty() && s[0] == '+') ++b;
    const auto [p, ec] = std::from_chars(b, s.data() + s.size(), v);
    return ec == std::errc() && p == s.data() + s.size() && b != s.data() + s.size();
}

bool to_double(const std::string& s, double& v) {
    const char* b = s.data();
    if (!s.empty() && s[0] == '+') ++b;
    const auto [p, ec] = std::from_chars(b, s.data() + s.size(), v);
    return ec == std::errc() && p == s.data() + s.size() && b != s.data() + s.size();
}

std::string fmt(double v) {
    char buf[64];
    const auto [p, ec] = std::to_chars(buf, buf + sizeof(buf), v, std::chars_format::general, 17);
    return std::string(buf, p);
}

/// A pose with exactly the given numbers, after checking that they form a rigid transform.
Pose exact_pose(const std::array<double, 12>& m) {
    pose_from_3x4(m);  // throws InputError when not rigid
    Pose pose = Pose::Identity();
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) pose.matrix()(r, c) = m[static_cast<std::size_t>(r * 4 + c)];
    return pose;
}

// ------------------------------------------------------------------------------ rig.json

/// Context for rig.json errors: "FILE: sensor 'ID': key: problem".
struct RigContext {
    const fs::path& path;
    std::string where;
    [[noreturn]] void fail(const std::string& problem) const {
        io::fail(path, where.empty() ? problem : where + ": " + problem);
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

constexpr const char* kPoseColumns[12] = {"r00", "r01", "r02", "t0",  "r10", "r11",
                                          "r12", "t1",  "r20", "r21", "r22", "t2"};

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
// never ends in a partial line.
void append_line(const fs::path& path, const std::string& line) {
    std::error_code ec;
    const std::uintmax_t before = fs::exists(path, ec) ? fs::file_size(path, ec) : 0;
    bool ok = false;
    {
        std::ofstream out(path, std::ios::app | std::ios::binary);
        if (!out) throw IoError(path.string() + ": cannot open for appending");
        out << line << '\n';
        out.flush();
        ok = static_cast<bool>(out);
    }
    if (!ok) {
        if (!ec) fs::resize_file(path, before, ec);
        throw IoError(path.string() + ": write failed (disk full?)");
    }
}

// ------------------------------------------------------------------------------ layouts

PinholeIntrinsics default_intrinsics(double cx, double cy) {
    PinholeIntrinsics k;
    k.width = 640;
    k.height = 480;
    k.fx = k.fy = 525.0;
    k.cx = cx;
    k.cy = cy;
    return k;
}

std::string absolute_path(const fs::path& p) { return fs::absolute(p).lexically_normal().string(); }

std::vector<fs::path> list_files(const fs::path& dir) {
    std::vector<fs::path> files;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir, ec))
        if (e.is_regular_file()) files.push_back(e.path());
    std::sort(files.begin(), files.end());
    return files;
}

bool has_file(const fs::path& p) {
    std::error_code ec;
    return fs::is_regular_file(p, ec);
}
bool has_dir(const fs::path& p) {
    std::error_code ec;
    return fs::is_directory(p, ec);
}

/// The "frames with OpenCV camera xml" layout (shared/data/multiview/uva_cv2_person_kinect1).
Capture open_uva(const fs::path& root, const std::vector<fs::path>& xmls) {
    Capture cap;
    cap.root = root;
    cap.layout = "uva";
    SensorSpec s;
    s.id = "camera";
    s.model = "kinect_v1";
    s.depth_scale = 1000.0;
    s.has_world_from_depth = false;  // poses are per frame
    std::vector<FrameRecord> frames;
    static const std::regex kName(R"((\d+)_camera\.xml)");
    for (const fs::path& xml : xmls) {
        std::smatch m;
        const std::string name = xml.filename().string();
        std::regex_match(name, m, kName);
        const std::string stem = m[1].str();
        cv::Mat k, r, t;
        try {
            cv::FileStorage fsx(xml.string(), cv::FileStorage::READ);
            if (!fsx.isOpened()) fail(xml, "cannot parse OpenCV FileStorage XML");
            fsx["intrinsic"] >> k;
            fsx["R"] >> r;
            fsx["t"] >> t;
        } catch (const cv::Exception& e) {
            fail(xml, std::string("cannot parse OpenCV FileStorage XML: ") + e.what());
        }
        if (k.rows != 3 || k.cols != 3 || r.rows != 3 || r.cols != 3 || t.total() != 3)
            fail(xml, "expected intrinsic 3x3, R 3x3 and t 3x1");
        k.convertTo(k, CV_64F);
        r.convertTo(r, CV_64F);
        t.convertTo(t, CV_64F);
        FrameRecord f;
        if (!to_int64(stem, f.index)) fail(xml, "bad frame number");
        f.time_ns = f.index * kFramePeriodNs;  // no timestamps in this layout: 30 fps assumed
        f.depth = absolute_path(root / (stem + "_depth.png"));
        f.color = absolute_path(root / (stem + ".jpg"));
        if (has_file(root / (stem + "_mask.jpg")))
            f.mask = absolute_path(root / (stem + "_mask.jpg"));
        std::array<double, 12> m34{};
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j)
                m34[static_cast<std::size_t>(i * 4 + j)] = r.at<double>(i, j);
            m34[static_cast<std::size_t>(i * 4 + 3)] = t.at<double>(i);
        }
        try {
            // Stored as float: re-orthonormalise (the values are rigid to ~1e-7).
            f.world_from_depth = pose_from_3x4(m34);
        } catch (const InputError& e) {
            fail(xml, std::string("R, t is not a rigid transform: ") + e.what());
        }
        if (frames.empty()) {
            s.depth.fx = k.at<double>(0, 0);
            s.depth.fy = k.at<double>(1, 1);
            s.depth.cx = k.at<double>(0, 2);
            s.depth.cy = k.at<double>(1, 2);
            // The image size is not in the xml: read it from the first depth image.
            const cv::Mat d = cv::imread(f.depth, cv::IMREAD_UNCHANGED);
            if (d.empty()) fail(f.depth, "missing or unreadable depth image");
            s.depth.width = d.cols;
            s.depth.height = d.rows;
            try {
                s.depth.check();
            } catch (const InputError& e) {
                fail(xml, e.what());
            }
            s.color = s.depth;  // depth is registered to the colour image
        }
        frames.push_back(std::move(f));
    }
    std::sort(frames.begin(), frames.end(),
              [](const FrameRecord& a, const FrameRecord& b) { return a.index < b.index; });
    cap.rig.sensors.push_back(s);
    cap.frames[s.id] = std::move(frames);
    return cap;
}

/// TUM list file: "timestamp path" lines, '#' comments.
std::vector<std::pair<double, std::string>> read_tum_list(const fs::path& path) {
    std::istringstream in(read_text(path));
    std::vector<std::pair<double, std::string>> out;
    std::string line;
    std::size_t number = 0;
    while (std::getline(in, line)) {
        ++number;
        const std::string t = trim(line);
        if (t.empty() || t[0] == '#') continue;
        const auto cells = split_ws(t);
        double stamp = 0;
        if (cells.size() < 2 || !to_double(cells[0], stamp))
            fail(path, "line " + std::to_string(number) + ": expected 'timestamp path'");
        out.emplace_back(stamp, cells[1]);
    }
    return out;
}

Capture open_tum(const fs::path& root) {
    Capture cap;
    cap.root = root;
    cap.layout = "tum";
    SensorSpec s;
    s.id = "camera";
    s.model = "kinect_v1";
    s.depth = default_intrinsics(319.5, 239.5);  // TUM default (Freiburg) intrinsics
    s.color = s.depth;
    s.depth_scale = 5000.0;
    s.has_world_from_depth = false;
    std::vector<FrameRecord> frames;
    if (has_file(root / "depth.txt")) {
        const auto depth = read_tum_list(root / "depth.txt");
        const auto rgb = has_file(root / "rgb.txt") ? read_tum_list(root / "rgb.txt")
                                                    : std::vector<std::pair<double, std::string>>{};
        // Optional ground truth: "timestamp tx ty tz qx qy qz qw" (camera-to-world).
        std::vector<std::pair<double, Pose>> truth;
        if (has_file(root / "groundtruth.txt")) {
            std::istringstream in(read_text(root / "groundtruth.txt"));
            std::string line;
            while (std::getline(in, line)) {
                const std::string t = trim(line);
                if (t.empty() || t[0] == '#') continue;
                const auto c = split_ws(t);
                double v[8];
                bool ok = c.size() == 8;
                for (std::size_t k = 0; ok && k < 8; ++k) ok = to_double(c[k], v[k]);
                if (!ok) fail(root / "groundtruth.txt", "bad line '" + t.substr(0, 60) + "'");
                Pose p = Pose::Identity();
                p.linear() =
                    Eigen::Quaterniond(v[7], v[4], v[5], v[6]).normalized().toRotationMatrix();
                p.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
                truth.emplace_back(v[0], p);
            }
        }
        const auto nearest = [](const auto& list, double stamp) -> std::optional<std::size_t> {
            std::optional<std::size_t> best;
            double best_dt = 0.020;  // associate within 20 ms
            for (std::size_t k = 0; k < list.size(); ++k) {
                const double dt = std::abs(list[k].first - stamp);
                if (dt <= best_dt) {
                    best_dt = dt;
                    best = k;
                }
            }
            return best;
        };
        for (std::size_t i = 0; i < depth.size(); ++i) {
            FrameRecord f;
            f.index = static_cast<std::int64_t>(i);
            f.time_ns = std::llround(depth[i].first * 1e9);
            f.depth = absolute_path(root / depth[i].second);
            if (const auto k = nearest(rgb, depth[i].first))
                f.color = absolute_path(root / rgb[*k].second);
            if (const auto k = nearest(truth, depth[i].first))
                f.world_from_depth = truth[*k].second;
            frames.push_back(std::move(f));
        }
    } else {
        // The single-frame form of the Open3D test data: TUM_color.png + TUM_depth.png.
        FrameRecord f;
        f.depth = absolute_path(root / "TUM_depth.png");
        if (has_file(root / "TUM_color.png")) f.color = absolute_path(root / "TUM_color.png");
        frames.push_back(std::move(f));
    }
    cap.rig.sensors.push_back(s);
    cap.frames[s.id] = std::move(frames);
    return cap;
}

/// Open3D PinholeCameraIntrinsic JSON (intrinsic_matrix column-major).
std::optional<PinholeIntrinsics> read_open3d_intrinsics(const fs::path& path) {
    json j;
    try {
        j = json::parse(read_text(path));
    } catch (const json::exception&) {
        return std::nullopt;
    }
    if (!j.is_object() || !j.contains("intrinsic_matrix")) return std::nullopt;
    const RigContext c{path, ""};
    const json& m = j.at("intrinsic_matrix");
    if (!m.is_array() || m.size() != 9) c.fail("intrinsic_matrix must have 9 numbers");
    PinholeIntrinsics k;
    const json& w = c.at(j, "width");
    const json& h = c.at(j, "height");
    if (!w.is_number_integer() || !h.is_number_integer()) c.fail("width/height must be integers");
    k.width = w.get<int>();
    k.height = h.get<int>();
    k.fx = c.number(m[0], "intrinsic_matrix[0]");
    k.fy = c.number(m[4], "intrinsic_matrix[4]");
    k.cx = c.number(m[6], "intrinsic_matrix[6]");
    k.cy = c.number(m[7], "intrinsic_matrix[7]");
    try {
        k.check();
    } catch (const InputError& e) {
        c.fail(e.what());
    }
    return k;
}

/// Open3D .log trajectory: "i j n" then 4 lines of a 4x4 camera-to-world matrix.
std::vector<Pose> read_log(const fs::path& path) {
    std::istringstream in(read_text(path));
    std::vector<Pose> poses;
    std::string line;
    std::size_t number = 0;
    while (std::getline(in, line)) {
        ++number;
        if (trim(line).empty()) continue;
        if (split_ws(line).size() != 3)
            fail(path, "line " + std::to_string(number) + ": expected 'i j n'");
        std::array<double, 16> m{};
        for (int r = 0; r < 4; ++r) {
            ++number;
            if (!std::getline(in, line))
                fail(path, "truncated matrix at line " + std::to_string(number));
            const auto c = split_ws(line);
            if (c.size() != 4)
                fail(path, "line " + std::to_string(number) + ": expected 4 numbers");
            for (int k = 0; k < 4; ++k)
                if (!to_double(c[static_cast<std::size_t>(k)],
                               m[static_cast<std::size_t>(r * 4 + k)]))
                    fail(path, "line " + std::to_string(number) + ": bad number");
        }
        try {
            poses.push_back(pose_from_4x4(m));
        } catch (const InputError& e) {
            fail(path, "line " + std::to_string(number) + ": " + e.what());
        }
    }
    return poses;
}

std::optional<fs::path> redwood_folder(const fs::path& root) {
    const auto is_frames = [](const fs::path& d) {
        return has_dir(d / "depth") && (has_dir(d / "color") || has_dir(d / "image"));
    };
    if (is_frames(root)) return root;
    std::vector<fs::path> subs;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(root, ec))
        if (e.is_directory() && is_frames(e.path())) subs.push_back(e.path());
    std::sort(subs.begin(), subs.end());
    if (subs.empty()) return std::nullopt;
    return subs.front();
}

Capture open_redwood(const fs::path& root, const fs::path& folder) {
    Capture cap;
    cap.root = root;
    cap.layout = "redwood";
    SensorSpec s;
    s.id = "camera";
    s.model = "primesense";
    s.depth = default_intrinsics(319.5, 239.5);  // Open3D PrimeSenseDefault
    s.depth_scale = 1000.0;
    s.has_world_from_depth = false;
    for (const fs::path& dir : {folder, root})
        for (const fs::path& f : list_files(dir))
            if (f.extension() == ".json")
                if (const auto k = read_open3d_intrinsics(f)) {
                    s.depth = *k;
                    goto found_intrinsics;
                }
found_intrinsics:
    s.color = s.depth;
    std::vector<Pose> poses;
    for (const fs::path& dir : {folder, root}) {
        for (const fs::path& f : list_files(dir))
            if (f.extension() == ".log") {
                poses = read_log(f);
                break;
            }
        if (!poses.empty()) break;
    }
    const fs::path color_dir = has_dir(folder / "color") ? folder / "color" : folder / "image";
    // Pairing: rgbd.match ("depth/x.png color/x.jpg") when present, else by sorted order.
    std::vector<std::pair<fs::path, fs::path>> pairs;
    if (has_file(folder / "rgbd.match")) {
        std::istringstream in(read_text(folder / "rgbd.match"));
        std::string line;
        while (std::getline(in, line)) {
            const auto c = split_ws(line);
            if (c.empty()) continue;
            if (c.size() != 2) fail(folder / "rgbd.match", "expected 'depth color' per line");
            pairs.emplace_back(folder / c[0], folder / c[1]);
        }
    } else {
        const auto depth = list_files(folder / "depth");
        const auto color = list_files(color_dir);
        for (std::size_t i = 0; i < depth.size(); ++i)
            pairs.emplace_back(depth[i], i < color.size() ? color[i] : fs::path());
    }
    if (!poses.empty() && poses.size() != pairs.size())
        fail(folder, "trajectory has " + std::to_string(poses.size()) + " poses for " +
                         std::to_string(pairs.size()) + " frames");
    std::vector<FrameRecord> frames, clean;
    // Noise-free depth of the same views (Augmented ICL-NUIM): a sibling "*clean*/depth".
    std::optional<fs::path> clean_dir;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(root, ec))
        if (e.is_directory() && e.path() != folder &&
            e.path().filename().string().find("clean") != std::string::npos &&
            has_dir(e.path() / "depth"))
            clean_dir = e.path() / "depth";
    for (std::size_t i = 0; i < pairs.size(); ++i) {
        FrameRecord f;
        f.index = static_cast<std::int64_t>(i);
        f.time_ns = f.index * kFramePeriodNs;  // no timestamps in this layout: 30 fps assumed
        f.depth = absolute_path(pairs[i].first);
        if (!pairs[i].second.empty()) f.color = absolute_path(pairs[i].second);
        if (!poses.empty()) f.world_from_depth = poses[i];
        if (clean_dir && has_file(*clean_dir / pairs[i].first.filename())) {
            FrameRecord c = f;
            c.depth = absolute_path(*clean_dir / pairs[i].first.filename());
            clean.push_back(std::move(c));
        }
        frames.push_back(std::move(f));
    }
    cap.rig.sensors.push_back(s);
    cap.frames[s.id] = std::move(frames);
    if (!clean.empty()) {
        SensorSpec c = s;
        c.id = "clean";
        c.model = "ground_truth";
        cap.rig.sensors.push_back(c);
        cap.frames[c.id] = std::move(clean);
    }
    return cap;
}

cv::Mat read_image(const std::string& file, int flags, const char* what) {
    if (!has_file(file)) fail(file, std::string("missing ") + what + " image");
    cv::Mat image;
    try {
        image = cv::imread(file, flags);
    } catch (const cv::Exception& e) {
        fail(file, std::string("cannot decode ") + what + " image: " + e.what());
    }
    if (image.empty()) fail(file, std::string("cannot decode ") + what + " image");
    return image;
}

void check_size(const std::string& file, const cv::Mat& image, const PinholeIntrinsics& k,
                const char* what) {
    if (image.cols != k.width || image.rows != k.height)
        fail(file, std::string(what) + " image is " + std::to_string(image.cols) + "x" +
                       std::to_string(image.rows) + " but the rig declares " +
                       std::to_string(k.width) + "x" + std::to_string(k.height));
}

std::string frame_name(std::int64_t index) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%06lld", static_cast<long long>(index));
    return buf;
}

}  // namespace

// ---------------------------------------------------------------------------------------

const SensorSpec& Rig::sensor(const std::string& id) const {
    for (const SensorSpec& s : sensors)
        if (s.id == id) return s;
    throw InputError("no sensor '" + id + "' in the rig");
}

Rig read_rig(const fs::path& path) {
    json j;
    try {
        j = json::parse(read_text(path));
    } catch (const json::parse_error& e) {
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
    std::vector<fs::path> xmls;
    static const std::regex kCameraXml(R"(\d+_camera\.xml)");
    for (const fs::path& f : list_files(root))
        if (std::regex_match(f.filename().string(), kCameraXml)) xmls.push_back(f);
    if (!xmls.empty()) return open_uva(root, xmls);
    if (has_file(root / "depth.txt") || has_file(root / "TUM_depth.png")) return open_tum(root);
    if (const auto folder = redwood_folder(root)) return open_redwood(root, *folder);
    fail(root,
         "not a capture folder (no rig.json, no TUM depth.txt or TUM_depth.png, no "
         "color/ + depth/ folders, no NNN_camera.xml frames)");
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
    const cv::Mat raw = read_image(depth_file, cv::IMREAD_UNCHANGED, "depth");
    cv::Mat color;
    std::string color_file;
    if (!r.color.empty()) {
        color_file = resolve(r.color);
        color = read_image(color_file, cv::IMREAD_COLOR, "colour");
        check_size(color_file, color, s.color, "colour");
    }
    RgbdFrame frame = frame_from_stored(s, raw, color, depth_file);
    if (!r.mask.empty()) {
        const std::string mask_file = resolve(r.mask);
        const cv::Mat mask = read_image(mask_file, cv::IMREAD_GRAYSCALE, "mask");
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
    if (depth_m.cols != s.depth.width || depth_m.rows != s.depth.height)
        throw InputError("add_frame: sensor '" + sensor_id + "': depth is " +
                         std::to_string(depth_m.cols) + "x" + std::to_string(depth_m.rows) +
                         " but the rig declares " + std::to_string(s.depth.width) + "x" +
                         std::to_string(s.depth.height));
    if (!color_bgr.empty()) {
        if (color_bgr.type() != CV_8UC3) throw InputError("add_frame: colour must be CV_8UC3 BGR");
        if (color_bgr.cols != s.color.width || color_bgr.rows != s.color.height)
            throw InputError("add_frame: sensor '" + sensor_id + "': colour is " +
                             std::to_string(color_bgr.cols) + "x" + std::to_string(color_bgr.rows) +
                             " but the rig declares " + std::to_string(s.color.width) + "x" +
                             std::to_string(s.color.height));
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
        write_image_atomic(dir / color_rel, color_bgr, {cv::IMWRITE_JPEG_QUALITY, 95});
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
            for (double v : pose_to_3x4(*world_from_depth)) line += "," + fmt(v);
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

void write_image_atomic(const fs::path& path, const cv::Mat& image,
                        const std::vector<int>& params) {
    if (image.empty()) throw InputError(path.string() + ": empty image, nothing written");
    std::vector<unsigned char> bytes;
    try {
        if (!cv::imencode(path.extension().string(), image, bytes, params))
            throw IoError(path.string() + ": cannot encode image");
    } catch (const cv::Exception& e) {
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
