#include "io/internal/capture_common.hpp"

#include <algorithm>
#include <charconv>
#include <fstream>
#include <sstream>

namespace rgbd::io::internal {

cv::Mat read_capture_image(const std::string& file, ImageMode mode, const char* what) {
    if (!has_file(file)) fail(file, std::string("missing ") + what + " image");
    try {
        return decode_image(read_file_bytes(file), mode, "");
    } catch (const IoError& e) {
        fail(file, std::string("cannot decode ") + what + " image: " + e.what());
    }
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

/// A pose with exactly the given numbers, after checking that they form a rigid transform.
Pose exact_pose(const std::array<double, 12>& m) {
    pose_from_3x4(m);  // throws InputError when not rigid
    Pose pose = Pose::Identity();
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) pose.matrix()(r, c) = m[static_cast<std::size_t>(r * 4 + c)];
    return pose;
}

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

}  // namespace rgbd::io::internal
