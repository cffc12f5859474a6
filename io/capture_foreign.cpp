// Foreign capture layouts read by open_capture: UvA (OpenCV xml cameras), TUM RGB-D,
// Open3D/Redwood and the APC vision toolbox scenes (Zeng et al., ICRA 2017). See
// io/capture_folder.hpp and docs/formats.md.
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
#include "io/internal/capture_common.hpp"
#include "toolkit/error.hpp"

namespace rgbd::io::internal {

namespace {

constexpr std::int64_t kFramePeriodNs = 33'333'333;  // 30 fps, for layouts without timestamps

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
    // Through 64 bits and a range check: get<int>() would wrap 2^32 + 8 around to 8.
    const std::int64_t width = w.get<std::int64_t>(), height = h.get<std::int64_t>();
    if (width <= 0 || height <= 0 || width > 100000 || height > 100000)
        c.fail("width and height must be in 1..100000");
    k.width = static_cast<int>(width);
    k.height = static_cast<int>(height);
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

/// The camera of a foreign layout: id "camera", the sensor `model`, depth PNG values
/// `depth_scale` per metre, no rig pose (poses, where the layout has them, are per frame).
SensorSpec foreign_camera(const std::string& model, double depth_scale) {
    SensorSpec s;
    s.id = "camera";
    s.model = model;
    s.depth_scale = depth_scale;
    s.has_world_from_depth = false;
    return s;
}

/// An empty capture of a foreign `layout` at `root`, for add_sensor to fill.
Capture foreign_capture(const fs::path& root, const std::string& layout) {
    Capture cap;
    cap.root = root;
    cap.layout = layout;
    return cap;
}

void add_sensor(Capture& cap, const SensorSpec& s, std::vector<FrameRecord> frames) {
    cap.rig.sensors.push_back(s);
    cap.frames[s.id] = std::move(frames);
}

}  // namespace

/// The "frames with OpenCV camera xml" layout (shared/data/multiview/uva_cv2_person_kinect1).
Capture open_uva(const fs::path& root, const std::vector<fs::path>& xmls) {
    Capture cap = foreign_capture(root, "uva");
    SensorSpec s = foreign_camera("kinect_v1", 1000.0);
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
            const cv::Mat d = read_capture_image(f.depth, ImageMode::kUnchanged, "depth");
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
    add_sensor(cap, s, std::move(frames));
    return cap;
}

Capture open_tum(const fs::path& root) {
    Capture cap = foreign_capture(root, "tum");
    SensorSpec s = foreign_camera("kinect_v1", 5000.0);
    s.depth = default_intrinsics(319.5, 239.5);  // TUM default (Freiburg) intrinsics
    s.color = s.depth;
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
    add_sensor(cap, s, std::move(frames));
    return cap;
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
    Capture cap = foreign_capture(root, "redwood");
    SensorSpec s = foreign_camera("primesense", 1000.0);
    s.depth = default_intrinsics(319.5, 239.5);  // Open3D PrimeSenseDefault
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
    add_sensor(cap, s, std::move(frames));
    if (!clean.empty()) {
        SensorSpec c = s;
        c.id = "clean";
        c.model = "ground_truth";
        add_sensor(cap, c, std::move(clean));
    }
    return cap;
}

// ------------------------------------------------------------------------------ APC

namespace {

/// One '#'-titled block of cam.info.txt: the title and the rows of numbers below it.
struct CamInfoBlock {
    std::string title;  ///< the words of the '#' line after '#', joined by single spaces
    std::vector<std::vector<double>> rows;
};

std::string join_words(const std::string& s) {
    std::string out;
    for (const std::string& w : split_ws(s)) out += (out.empty() ? "" : " ") + w;
    return out;
}

/// The blocks of cam.info.txt in file order; numbers may be separated by tabs or spaces.
std::vector<CamInfoBlock> read_cam_info(const fs::path& path) {
    std::istringstream in(read_text(path));
    std::vector<CamInfoBlock> blocks;
    std::string line;
    std::size_t number = 0;
    while (std::getline(in, line)) {
        ++number;
        const std::string t = trim(line);
        if (t.empty()) continue;
        if (t[0] == '#') {
            blocks.push_back({join_words(t.substr(1)), {}});
            continue;
        }
        const std::string at = "line " + std::to_string(number);
        if (blocks.empty()) fail(path, at + ": numbers before the first '# title' line");
        std::vector<double> row;
        for (const std::string& cell : split_ws(t)) {
            double v = 0;
            if (!to_double(cell, v) || !std::isfinite(v))
                fail(path, at + " ('" + blocks.back().title + "'): bad number '" +
                               cell.substr(0, 30) + "'");
            row.push_back(v);
        }
        blocks.back().rows.push_back(std::move(row));
    }
    return blocks;
}

/// The rows x cols matrix (row-major) of the block titled `title`; errors name it as `what`.
std::vector<double> cam_info_matrix(const fs::path& path, const std::vector<CamInfoBlock>& blocks,
                                    const std::string& title, const std::string& what,
                                    std::size_t rows, std::size_t cols) {
    const CamInfoBlock* found = nullptr;
    for (const CamInfoBlock& b : blocks)
        if (b.title == title) {
            if (found) fail(path, what + " is given twice");
            found = &b;
        }
    if (!found) fail(path, "no " + what + " (block '# " + title + "')");
    if (found->rows.size() != rows)
        fail(path, what + " has " + std::to_string(found->rows.size()) + " rows (expected " +
                       std::to_string(rows) + ")");
    std::vector<double> m;
    for (std::size_t r = 0; r < rows; ++r) {
        if (found->rows[r].size() != cols)
            fail(path, what + ": row " + std::to_string(r + 1) + " has " +
                           std::to_string(found->rows[r].size()) + " numbers (expected " +
                           std::to_string(cols) + ")");
        m.insert(m.end(), found->rows[r].begin(), found->rows[r].end());
    }
    return m;
}

/// A 3x3 pinhole matrix [fx 0 cx; 0 fy cy; 0 0 1] of a width x height image.
PinholeIntrinsics cam_info_intrinsics(const fs::path& path, const std::vector<CamInfoBlock>& blocks,
                                      const std::string& title, const std::string& what, int width,
                                      int height) {
    const auto m = cam_info_matrix(path, blocks, title, what, 3, 3);
    if (std::abs(m[1]) > 1e-9 || std::abs(m[3]) > 1e-9 || std::abs(m[6]) > 1e-9 ||
        std::abs(m[7]) > 1e-9 || std::abs(m[8] - 1.0) > 1e-9)
        fail(path, what + " is not a pinhole matrix [fx 0 cx; 0 fy cy; 0 0 1]");
    PinholeIntrinsics k;
    k.width = width;
    k.height = height;
    k.fx = m[0];
    k.fy = m[4];
    k.cx = m[2];
    k.cy = m[5];
    try {
        k.check();
    } catch (const InputError& e) {
        fail(path, what + ": " + e.what());
    }
    return k;
}

/// A 4x4 rigid transform (metres); re-orthonormalised (the file has 9 significant digits).
Pose cam_info_pose(const fs::path& path, const std::vector<CamInfoBlock>& blocks,
                   const std::string& title, const std::string& what) {
    const auto m = cam_info_matrix(path, blocks, title, what, 4, 4);
    std::array<double, 16> a{};
    std::copy(m.begin(), m.end(), a.begin());
    try {
        return pose_from_4x4(a);
    } catch (const InputError& e) {
        fail(path, what + " is not a rigid transform: " + e.what());
    }
}

json pose_json(const Pose& p) {
    json rows = json::array();
    for (int r = 0; r < 4; ++r)
        rows.push_back({p.matrix()(r, 0), p.matrix()(r, 1), p.matrix()(r, 2), p.matrix()(r, 3)});
    return rows;
}

}  // namespace

Capture open_apc(const fs::path& root, const std::vector<fs::path>& depth) {
    const fs::path info = root / "cam.info.txt";
    const std::vector<CamInfoBlock> blocks = read_cam_info(info);
    Capture cap = foreign_capture(root, "apc");
    // The F200 is the SR300's predecessor (same coded-light principle, same 0.2-1.2 m range):
    // the denoisers' SR300 noise model. Depth: 0.1 mm units.
    SensorSpec s = foreign_camera("realsense_f200", 10000.0);
    s.noise_model = "sr300";
    s.depth_encoding = DepthEncoding::kApcRotated3;
    s.range_min_m = 0.2;
    s.range_max_m = 1.2;
    // The image size is not in cam.info.txt: read it from the first depth image.
    const cv::Mat first =
        read_capture_image(depth.front().string(), ImageMode::kUnchanged, "depth");
    // frame-N.depth.png is registered to the colour camera: it lies on the colour grid, so its
    // intrinsics are the colour ones and colour_from_depth is the identity. The raw depth
    // camera (raw/, its own intrinsics and the 25.7 mm depth-to-colour extrinsic) is kept in
    // the sensor's extra keys for reference only.
    s.color = cam_info_intrinsics(info, blocks, "Color camera intrinsic matrix",
                                  "colour intrinsics", first.cols, first.rows);
    s.depth = s.color;
    const PinholeIntrinsics raw = cam_info_intrinsics(info, blocks, "Depth camera intrinsic matrix",
                                                      "depth intrinsics", first.cols, first.rows);
    const Pose color_from_raw = cam_info_pose(
        info, blocks, "Depth-to-color camera extrinsic matrix", "depth-to-colour extrinsic");
    s.extra["raw_depth"] = {
        {"folder", "raw"},
        {"encoding", to_string(DepthEncoding::kApcRotated3)},
        {"intrinsics", {{"fx", raw.fx}, {"fy", raw.fy}, {"cx", raw.cx}, {"cy", raw.cy}}},
        {"color_from_depth", pose_json(color_from_raw)}};
    json apc = {{"world_from_bin",
                 pose_json(cam_info_pose(info, blocks, "Bin-to-world transformation matrix",
                                         "bin-to-world transform"))}};
    for (const CamInfoBlock& b : blocks) {  // "# Environment: shelf", "# Bin ID: B", ...
        const auto colon = b.title.find(':');
        if (!b.rows.empty() || colon == std::string::npos) continue;
        std::string key = join_words(b.title.substr(0, colon));
        std::transform(key.begin(), key.end(), key.begin(),
                       [](unsigned char c) { return c == ' ' ? '_' : std::tolower(c); });
        const std::string value = trim(b.title.substr(colon + 1));
        apc[key] = json::parse(value, nullptr, /*allow_exceptions=*/false);
        if (apc[key].is_discarded()) apc[key] = value;  // not JSON: the text
    }
    cap.rig.extra["apc"] = apc;

    std::vector<FrameRecord> frames;
    for (const fs::path& file : depth) {
        const std::string name = file.filename().string();
        const std::string stem = name.substr(0, name.size() - std::string(".depth.png").size());
        FrameRecord f;
        if (!to_int64(stem.substr(std::string("frame-").size()), f.index))
            fail(file, "bad frame number");
        f.time_ns = f.index * 1'000'000'000;  // no timestamps in this layout: 1 s per frame
        f.depth = absolute_path(file);
        if (has_file(root / (stem + ".color.png")))
            f.color = absolute_path(root / (stem + ".color.png"));
        f.world_from_depth = cam_info_pose(
            info, blocks, "Camera-to-world extrinsic matrix (camera pose) for " + stem,
            "pose of " + stem);
        frames.push_back(std::move(f));
    }
    std::sort(frames.begin(), frames.end(),
              [](const FrameRecord& a, const FrameRecord& b) { return a.index < b.index; });
    add_sensor(cap, s, std::move(frames));
    return cap;
}
}  // namespace rgbd::io::internal
