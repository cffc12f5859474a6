// Data for the examples, made in code so that they run without files: a capture folder of a
// striped sphere seen by a ring of depth cameras (exact ray-sphere depth, 1 mm steps), and the
// sphere as a reference mesh.
#pragma once

#include <cmath>
#include <filesystem>
#include <numbers>
#include <opencv2/core.hpp>
#include <string>

#include "io/capture_folder.hpp"
#include "toolkit/mesh.hpp"

namespace examples {

inline constexpr double kRadius = 0.15;  ///< sphere radius (m), centred at the world origin

/// Writes a capture folder (rig.json, one frame set) of the sphere seen by `count` 320x240
/// cameras on a ring of radius 0.8 m, each looking at the centre from 0.3 m above it (the
/// underside stays unseen) or, with `above_and_below`, from 0.3 m above and below in turn.
inline std::filesystem::path make_capture(const std::filesystem::path& root, int count = 6,
                                          bool above_and_below = false) {
    std::filesystem::remove_all(root);
    rgbd::io::Rig rig;
    for (int s = 0; s < count; ++s) {
        const double a = 2 * std::numbers::pi * s / count;
        const Eigen::Vector3d eye(0.8 * std::cos(a), 0.8 * std::sin(a),
                                  above_and_below && s % 2 ? -0.3 : 0.3);
        const Eigen::Vector3d z = -eye.normalized();
        const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
        rgbd::io::SensorSpec sensor;
        sensor.id = "cam" + std::to_string(s);
        sensor.model = "kinect_v2";
        sensor.depth = sensor.color = {320, 240, 280.0, 280.0, 159.5, 119.5, {}};
        sensor.range_min_m = 0.3;
        sensor.range_max_m = 3.0;
        sensor.world_from_depth.linear() << x, z.cross(x), z;  // OpenCV camera: x right, y down
        sensor.world_from_depth.translation() = eye;
        rig.sensors.push_back(sensor);
    }
    rgbd::io::CaptureWriter writer(root, rig);
    rgbd::io::FrameSet set;
    for (const auto& sensor : rig.sensors) {
        cv::Mat depth(240, 320, CV_32FC1, cv::Scalar(0)), color(240, 320, CV_8UC3);
        const Eigen::Vector3d eye = sensor.world_from_depth.translation();
        for (int v = 0; v < 240; ++v)
            for (int u = 0; u < 320; ++u) {
                color.at<cv::Vec3b>(v, u) = {90, 90, 90};
                // Ray eye + t d with camera z = t (d has z = 1 in the camera frame).
                const Eigen::Vector3d d =
                    sensor.world_from_depth.linear() * sensor.depth.unproject(u, v, 1.0);
                const double b = eye.dot(d), disc = b * b - d.squaredNorm() * (eye.squaredNorm() -
                                                                               kRadius * kRadius);
                if (disc < 0) continue;
                const double t = std::round(1000 * (-b - std::sqrt(disc)) / d.squaredNorm()) / 1000;
                const Eigen::Vector3d p = eye + t * d;
                depth.at<float>(v, u) = static_cast<float>(t);
                const auto stripe = static_cast<unsigned char>(128 + 100 * std::sin(40 * p.z()));
                color.at<cv::Vec3b>(v, u) = {stripe, 140, static_cast<unsigned char>(255 - stripe)};
            }
        writer.add_frame(sensor.id, 0, 0, depth, color);
        set.frames.push_back(0);
    }
    writer.add_frameset(set);
    return root;
}

/// The sphere as a closed mesh (UV sphere, `rings` x 2 `rings` quads split in triangles).
inline rgbd::Mesh reference_sphere(int rings = 48) {
    rgbd::Mesh mesh;
    std::vector<rgbd::Mesh::Vertex_index> v;
    const auto top = mesh.add_vertex({0, 0, kRadius}), bottom = mesh.add_vertex({0, 0, -kRadius});
    for (int i = 1; i < rings; ++i)
        for (int j = 0; j < 2 * rings; ++j) {
            const double th = std::numbers::pi * i / rings, ph = std::numbers::pi * j / rings;
            v.push_back(
                mesh.add_vertex({kRadius * std::sin(th) * std::cos(ph),
                                 kRadius * std::sin(th) * std::sin(ph), kRadius * std::cos(th)}));
        }
    const auto at = [&](int i, int j) { return v[(i - 1) * 2 * rings + (j % (2 * rings))]; };
    for (int j = 0; j < 2 * rings; ++j) {
        mesh.add_face(top, at(1, j), at(1, j + 1));
        mesh.add_face(bottom, at(rings - 1, j + 1), at(rings - 1, j));
        for (int i = 1; i + 1 < rings; ++i) {
            mesh.add_face(at(i, j), at(i + 1, j), at(i + 1, j + 1));
            mesh.add_face(at(i, j), at(i + 1, j + 1), at(i, j + 1));
        }
    }
    return mesh;
}

}  // namespace examples
