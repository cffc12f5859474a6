// Per-view work on the nodes (rgbd-capture --video --fuse-on nodes, issue 20): what the hub asks
// for in its start message, and the view payload a node sends back (sensors/network/protocol.hpp
// PayloadKind::kView). Shared by cli/rgbd_node.cpp and cli/capture_video.cpp.
#pragma once

#include <cstdint>
#include <cstring>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "io/video.hpp"
#include "pipeline/video_fusion.hpp"
#include "toolkit/error.hpp"
#include "toolkit/point_cloud.hpp"

namespace rgbd::cli {

/// What a node needs to make fused-ready views of its sensor.
struct ViewRequest {
    Pose world_from_sensor = Pose::Identity();  ///< the rig's pose of this sensor
    std::optional<Eigen::Vector3d> centre;      ///< the rig's object centre (crop)
    double crop_radius_m = 0.6;
    bool clean = true;
};

inline nlohmann::json view_request_to_json(const ViewRequest& r) {
    nlohmann::json pose = nlohmann::json::array();
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) pose.push_back(r.world_from_sensor.matrix()(i, j));
    nlohmann::json v = {
        {"world_from_sensor", pose}, {"crop_radius_m", r.crop_radius_m}, {"clean", r.clean}};
    v["centre"] = r.centre ? nlohmann::json::array({r.centre->x(), r.centre->y(), r.centre->z()})
                           : nlohmann::json(nullptr);
    return {{"views", v}};
}

/// nullopt when the start message asks for frames (no "views"); InputError when malformed.
inline std::optional<ViewRequest> view_request_from_json(const std::string& text) {
    if (text.empty()) return std::nullopt;
    const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
    if (!j.is_object()) throw InputError("start message: not a JSON object");
    if (!j.contains("views")) return std::nullopt;
    const nlohmann::json& v = j["views"];
    ViewRequest r;
    try {
        std::array<double, 16> m{};
        const auto& pose = v.at("world_from_sensor");
        if (!pose.is_array() || pose.size() != 16) throw InputError("pose is not 16 numbers");
        for (std::size_t i = 0; i < 16; ++i) m[i] = pose[i].get<double>();
        r.world_from_sensor = pose_from_4x4(m);
        if (v.contains("centre") && v["centre"].is_array() && v["centre"].size() == 3)
            r.centre = Eigen::Vector3d(v["centre"][0].get<double>(), v["centre"][1].get<double>(),
                                       v["centre"][2].get<double>());
        r.crop_radius_m = v.value("crop_radius_m", 0.6);
        r.clean = v.value("clean", true);
    } catch (const nlohmann::json::exception& e) {
        throw InputError(std::string("start message: bad view request: ") + e.what());
    }
    return r;
}

/// A world-frame view as the two payloads of a view message.
inline void encode_view_payload(const PointCloud& view, std::vector<std::uint8_t>& xyz,
                                std::vector<std::uint8_t>& rgb) {
    const std::size_t n = view.size();
    xyz.resize(12 * n);
    rgb.assign(3 * n, 128);
    std::size_t k = 0;
    const bool colours = view.has_colors();
    std::optional<PointCloud::ColorMaps> cm;
    if (colours) cm = view.colors();
    for (auto i : view.points) {
        const Point_3& p = view.points.point(i);
        const float f[3] = {static_cast<float>(p.x()), static_cast<float>(p.y()),
                            static_cast<float>(p.z())};
        std::memcpy(xyz.data() + 12 * k, f, 12);  // little-endian hosts only (x86, ARM)
        if (cm) {
            const Rgb c = cm->get(i);
            rgb[3 * k] = c.r;
            rgb[3 * k + 1] = c.g;
            rgb[3 * k + 2] = c.b;
        }
        ++k;
    }
}

/// The points of a view message; false with a reason for inconsistent sizes or non-finite
/// coordinates.
inline bool decode_view_payload(const std::uint8_t* xyz, std::size_t xyz_bytes,
                                const std::uint8_t* rgb, std::size_t rgb_bytes,
                                io::ColoredPoints& out, std::string& error) {
    if (xyz_bytes % 12 != 0 || rgb_bytes != xyz_bytes / 4) {
        error = "view payload sizes do not match (" + std::to_string(xyz_bytes) + " and " +
                std::to_string(rgb_bytes) + " bytes)";
        return false;
    }
    const std::size_t n = xyz_bytes / 12;
    out.xyz.resize(n);
    out.rgb.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        float f[3];
        std::memcpy(f, xyz + 12 * i, 12);
        out.xyz[i] = Eigen::Vector3f(f[0], f[1], f[2]);
        if (!out.xyz[i].allFinite()) {
            error = "view payload has a non-finite point";
            return false;
        }
        out.rgb[i] = Rgb{rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]};
    }
    return true;
}

}  // namespace rgbd::cli
