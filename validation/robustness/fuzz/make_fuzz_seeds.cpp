// Writes the seed corpora of the fuzz targets (validation/robustness/fuzz.sh runs it): small
// valid inputs made with the toolkit's own writers, each prefixed by the selector byte its
// target expects. Usage: make_fuzz_seeds OUT_DIR  (creates OUT_DIR/<target>/seed_N).
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "algorithms/calibration/charuco_board.hpp"
#include "io/capture_folder.hpp"
#include "io/mesh_io.hpp"
#include "io/ply_stream.hpp"
#include "io/rvl.hpp"
#include "sensors/network/protocol.hpp"
#include "validation/robustness/fuzz/fuzz_support.hpp"

namespace {

namespace fs = std::filesystem;
using namespace rgbd;

class Corpus {
public:
    Corpus(const fs::path& out, const std::string& target) : dir_(out / target) {
        fs::create_directories(dir_);
    }
    void add(const std::string& bytes) {
        std::ofstream(dir_ / ("seed_" + std::to_string(n_++)), std::ios::binary) << bytes;
    }
    void add(char selector, const std::string& bytes) { add(std::string(1, selector) + bytes); }

private:
    fs::path dir_;
    int n_ = 0;
};

PointCloud small_cloud(bool normals, bool colors) {
    PointCloud cloud;
    if (normals) cloud.points.add_normal_map();
    std::optional<PointCloud::ColorMaps> c;
    if (colors) c = cloud.add_colors();
    for (int i = 0; i < 6; ++i) {
        const auto idx = *cloud.points.insert(Point_3(0.1 * i, std::sin(i) / 3.0, 1.0 + i * 1e-3));
        if (normals) cloud.points.normal(idx) = Vector_3(0, 0, -1);
        if (colors) c->set(idx, {static_cast<std::uint8_t>(40 * i), 100, 200});
    }
    cloud.view.id = 3;
    cloud.view.sensor = "k0";
    cloud.view.time_ns = 123456789;
    return cloud;
}

Mesh tetrahedron() {
    Mesh m;
    const auto a = m.add_vertex(Point_3(0, 0, 0)), b = m.add_vertex(Point_3(1, 0, 0)),
               c = m.add_vertex(Point_3(0, 1, 0)), d = m.add_vertex(Point_3(0, 0, 1));
    m.add_face(a, c, b);
    m.add_face(a, b, d);
    m.add_face(a, d, c);
    m.add_face(b, c, d);
    return m;
}

const char* const kAsciiPly =
    "ply\nformat ascii 1.0\ncomment rgbd:stream 1\nelement vertex 3\nproperty float x\n"
    "property float y\nproperty float z\nproperty uchar red\nproperty uchar green\n"
    "property uchar blue\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
    "0 0 1 255 0 0\n1 0 1 0 255 0\n0 1 1 0 0 255\n3 0 1 2\n";

void ply_stream(const fs::path& out) {
    Corpus c(out, "fuzz_ply_stream");
    std::ostringstream s1, s2, s3;
    io::write_points(s1, small_cloud(true, true));
    c.add(s1.str());
    io::write_points(s2, small_cloud(false, false));
    io::write_mesh(s2, tetrahedron(), ViewInfo{});
    c.add(s2.str());
    c.add(kAsciiPly);
    s3 << kAsciiPly;
    io::write_points(s3, small_cloud(true, false));
    c.add(s3.str());
}

void mesh_readers(const fs::path& out, const fs::path& tmp) {
    Corpus c(out, "fuzz_mesh_readers");
    io::write_mesh(tmp / "m.ply", tetrahedron());
    c.add(0, fuzz::slurp(tmp / "m.ply"));
    c.add(0, kAsciiPly);
    io::write_point_cloud(tmp / "c.ply", small_cloud(true, true));
    c.add(0, fuzz::slurp(tmp / "c.ply"));
    c.add(1, "OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n4 1 2 3 1\n");
    c.add(1, "COFF\n3 1 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0 0 0 255 255\n3 0 1 2\n");
    c.add(2,
          "# obj\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvn 0 0 1\nf 1 3 2\nf 1/1/1 2//1 4\n"
          "f -4 -1 -2\nf 2 3 4\n");
    c.add(3,
          "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F F\n"
          "COUNT 1 1 1 1\nWIDTH 3\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n"
          "0 0 1 4.2108e+06\n1 0 1 4.2108e+06\n0 1 1 4.2108e+06\n");
    c.add(3,
          "VERSION 0.7\nFIELDS x y z normal_x normal_y normal_z\nSIZE 4 4 4 4 4 4\n"
          "TYPE F F F F F F\nCOUNT 1 1 1 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary\n" +
              std::string(48, '\0'));
    c.add(4, "0 0 1\n1 0 1 0 0 1\n0.5 0.5 1.5\n");
}

void capture_folder(const fs::path& out, const fs::path& tmp) {
    Corpus c(out, "fuzz_capture_folder");
    cv::Mat depth(6, 8, CV_32FC1, cv::Scalar(1.5f));
    depth.at<float>(2, 3) = std::nanf("");
    Pose pose = Pose::Identity();
    pose.translation() = Eigen::Vector3d(0.1, 0.2, 0.3);
    const auto files = fuzz::write_small_capture(tmp / "capture", depth, pose);
    for (int role = 0; role < 4; ++role) c.add(char(role), fuzz::slurp(files[role]));
}

void foreign_layouts(const fs::path& out) {
    Corpus c(out, "fuzz_foreign_layouts");
    c.add(0, "# depth maps\n# timestamp filename\n1.0 depth/1.0.png\n");
    c.add(1, "# color images\n1.0 rgb/1.0.png\n1.01 rgb/1.0.png\n");
    c.add(2,
          "# ground truth trajectory\n1.0 0.1 0.2 0.3 0 0 0 1\n1.02 0.1 0.2 0.3 0 0 0.7071068 "
          "0.7071068\n");
    // The Redwood folder of the target has 8x6 images.
    c.add(3,
          R"({"width": 8, "height": 6, "intrinsic_matrix": [7.0, 0, 0, 0, 7.0, 0, 3.5, 2.5, 1]})");
    c.add(4, "0 0 1\n1 0 0 0.1\n0 1 0 0.2\n0 0 1 0.3\n0 0 0 1\n");
}

void rvl_and_network(const fs::path& out) {
    std::vector<std::uint16_t> depth(64 * 48);
    for (std::size_t i = 0; i < depth.size(); ++i)
        depth[i] = (i % 7 == 0) ? 0 : static_cast<std::uint16_t>(800 + (i * 13) % 500);
    std::vector<std::uint8_t> rvl;
    io::rvl_compress(depth.data(), depth.size(), rvl);
    Corpus r(out, "fuzz_rvl");
    std::string small(2, '\0');
    small[0] = static_cast<char>(depth.size() & 0xff);
    small[1] = static_cast<char>(depth.size() >> 8);
    r.add(small + std::string(rvl.begin(), rvl.end()));
    std::vector<std::uint8_t> zeros(16, 0), rvl0;
    io::rvl_compress(reinterpret_cast<const std::uint16_t*>(zeros.data()), 8, rvl0);
    r.add(std::string("\x08\x00", 2) + std::string(rvl0.begin(), rvl0.end()));

    Corpus f(out, "fuzz_frame_message");
    std::vector<std::uint8_t> jpeg;
    cv::imencode(".jpg", cv::Mat(48, 64, CV_8UC3, cv::Scalar(1, 2, 3)), jpeg);
    sensors::net::FrameHeader h;
    h.session = 42;
    h.sensor_id = "k0";
    h.index = 7;
    h.device_ns = 1000;
    h.node_ns = 2000;
    h.width = 64;
    h.height = 48;
    std::vector<std::uint8_t> msg;
    sensors::net::encode_frame(h, rvl.data(), rvl.size(), jpeg.data(), jpeg.size(), msg);
    f.add(std::string(msg.begin(), msg.end()));
    sensors::net::encode_frame(h, rvl.data(), rvl.size(), nullptr, 0, msg);
    f.add(std::string(msg.begin(), msg.end()));
    sensors::net::ControlMessage m;
    m.type = sensors::net::ControlType::kHello;
    m.session = 42;
    m.json = R"({"sensor": {"id": "k0"}, "rate_hz": 30})";
    auto cm = sensors::net::encode_control(m);
    f.add(std::string(cm.begin(), cm.end()));
    m.type = sensors::net::ControlType::kProbeReply;
    m.seq = 3;
    m.t0 = 1;
    m.t1 = 2;
    m.t2 = 3;
    cm = sensors::net::encode_control(m);
    f.add(std::string(cm.begin(), cm.end()));
}

/// Board files as rgbd-synth writes them (BoardSpec::to_json, indented): the default board,
/// a portrait one with another dictionary, the smallest one, one with only some keys, and the
/// input that aborted the target (issue 39: markers too small to draw at 240 pixels; also kept
/// in tests/algorithms/calibration/board_file_regression_test.cpp).
void calibration_board(const fs::path& out) {
    Corpus c(out, "fuzz_calibration_board");
    calibration::BoardSpec b;
    c.add(b.to_json().dump(2) + "\n");
    b.squares_x = 5;
    b.squares_y = 8;
    b.square_m = 0.03;
    b.marker_m = 0.022;
    b.dictionary = "DICT_4X4_50";
    c.add(b.to_json().dump(2) + "\n");
    b.squares_x = b.squares_y = 2;
    b.dictionary = "DICT_ARUCO_ORIGINAL";
    c.add(b.to_json().dump());
    c.add(R"({"squares_x": 9, "square_m": 0.1})");
    c.add(R"({"squares_x": 6, "squares_y": 32})");
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 2 || std::string(argv[1]) == "--help") {
        std::cerr << "usage: make_fuzz_seeds OUT_DIR  (writes OUT_DIR/<fuzz target>/seed_N)\n";
        return argc == 2 ? 0 : 2;
    }
    try {
        const fs::path out = argv[1];
        const fs::path tmp = out / ".work";
        fs::remove_all(tmp);
        fs::create_directories(tmp);
        ply_stream(out);
        mesh_readers(out, tmp);
        capture_folder(out, tmp);
        foreign_layouts(out);
        rvl_and_network(out);
        calibration_board(out);
        fs::remove_all(tmp);
    } catch (const std::exception& e) {
        std::cerr << "make_fuzz_seeds: " << e.what() << "\n";
        return 1;
    }
    return 0;
}
