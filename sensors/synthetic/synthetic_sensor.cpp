#include "sensors/synthetic/synthetic_sensor.hpp"

#include <cmath>
#include <thread>

#include "toolkit/error.hpp"

namespace rgbd::sensors {

namespace {

std::uint32_t hash32(std::uint32_t x) {
    x ^= x >> 16;
    x *= 0x7feb352dU;
    x ^= x >> 15;
    x *= 0x846ca68bU;
    x ^= x >> 16;
    return x;
}

struct Scene {
    double cx, cy, cz, r;  // sphere centre and radius (m, depth camera frame)
    double wall_z;         // wall distance (m)
    // Depth along the ray (x, y, 1) or 0: z of the first hit, and whether it is the sphere.
    double hit(double x, double y, bool& sphere) const {
        const double a = x * x + y * y + 1, b = -2 * (x * cx + y * cy + cz),
                     c = cx * cx + cy * cy + cz * cz - r * r;
        const double disc = b * b - 4 * a * c;
        sphere = disc >= 0;
        if (sphere) return (-b - std::sqrt(disc)) / (2 * a);
        return wall_z;
    }
};

}  // namespace

SyntheticSensor::SyntheticSensor(const SyntheticOptions& o) : options_(o) {
    check_range("synthetic sensor: rate", o.rate_hz, Range::open_closed(0, 1000));
    RGBD_CHECK(
        o.color_width > 0 && o.color_height > 0 && o.color_width <= 4096 && o.color_height <= 4096,
        "synthetic sensor: bad colour size");
    RGBD_CHECK(!o.id.empty(), "synthetic sensor: empty id");
    spec_.id = o.id;
    spec_.model = "synthetic_kinect_v2";
    spec_.depth.width = 512;
    spec_.depth.height = 424;
    spec_.depth.fx = spec_.depth.fy = 365.5;
    spec_.depth.cx = 256.0;
    spec_.depth.cy = 212.0;
    const double s = o.color_width / 1920.0;
    spec_.color.width = o.color_width;
    spec_.color.height = o.color_height;
    spec_.color.fx = spec_.color.fy = 1081.37 * s;
    spec_.color.cx = (959.5 + 0.5) * s - 0.5;
    spec_.color.cy = (539.5 + 0.5) * (o.color_height / 1080.0) - 0.5;
    spec_.depth_scale = 1000.0;
    spec_.range_min_m = 0.5;
    spec_.range_max_m = 4.5;
    spec_.color_from_depth.translation() = Eigen::Vector3d(0.052, 0, 0);
    spec_.noise_model = "kinect_v2";
}

void SyntheticSensor::render(std::int64_t index, cv::Mat& depth, cv::Mat& color) const {
    const double t = static_cast<double>(index) / options_.rate_hz;
    const Scene scene{0.4 * std::sin(2 * M_PI * 0.25 * t), 0.05, 1.6, 0.2, 3.0};
    depth.create(spec_.depth.height, spec_.depth.width, CV_16UC1);
    const PinholeIntrinsics& kd = spec_.depth;
    for (int v = 0; v < depth.rows; ++v) {
        std::uint16_t* row = depth.ptr<std::uint16_t>(v);
        for (int u = 0; u < depth.cols; ++u) {
            bool sphere = false;
            const double z = scene.hit((u - kd.cx) / kd.fx, (v - kd.cy) / kd.fy, sphere);
            const std::uint32_t h = hash32(
                static_cast<std::uint32_t>((index * 7919 + v) * 1031 + u));  // deterministic noise
            const double noise_m = options_.noise_mm * 1e-3 * ((h & 0xffff) / 32767.5 - 1.0);
            row[u] =
                (h >> 16) % 200 == 0
                    ? 0  // 0.5 % dropouts
                    : static_cast<std::uint16_t>(std::lround((z + noise_m * z * z / 4) * 1000.0));
        }
    }
    // Colour camera: 52 mm to the right of the depth camera (same orientation).
    color.create(spec_.color.height, spec_.color.width, CV_8UC3);
    const PinholeIntrinsics& kc = spec_.color;
    Scene shifted = scene;
    shifted.cx -= 0.052;
    for (int v = 0; v < color.rows; ++v) {
        cv::Vec3b* row = color.ptr<cv::Vec3b>(v);
        for (int u = 0; u < color.cols; ++u) {
            const double x = (u - kc.cx) / kc.fx, y = (v - kc.cy) / kc.fy;
            bool sphere = false;
            const double z = shifted.hit(x, y, sphere);
            if (sphere) {
                const double nz = (scene.cz - z) / scene.r;  // facing the camera: bright
                const auto shade = static_cast<std::uint8_t>(60 + 180 * std::clamp(nz, 0.0, 1.0));
                row[u] = cv::Vec3b(40, static_cast<std::uint8_t>(shade / 2), shade);
            } else {
                const int checker = (static_cast<int>(std::floor(x * z * 10)) +
                                     static_cast<int>(std::floor(y * z * 10))) &
                                    1;
                row[u] = checker ? cv::Vec3b(200, 190, 170) : cv::Vec3b(90, 80, 70);
            }
        }
    }
}

bool SyntheticSensor::start_at(std::int64_t monotonic_ns) {
    if (produced_ > 0) return false;
    start_ns_ = monotonic_ns;
    start_set_ = true;
    return true;
}

bool SyntheticSensor::next(SensorFrame& frame) {
    if (options_.max_frames > 0 && produced_ >= options_.max_frames) return false;
    const auto period_ns = static_cast<std::int64_t>(std::llround(1e9 / options_.rate_hz));
    if (produced_ == 0 && !start_set_) start_ns_ = (monotonic_ns() / period_ns + 1) * period_ns;
    const std::int64_t instant = start_ns_ + produced_ * period_ns;
    if (options_.realtime) {
        const std::int64_t wait = instant - monotonic_ns();
        if (wait > 0) std::this_thread::sleep_for(std::chrono::nanoseconds(wait));
    }
    render(produced_, frame.depth, frame.color);
    frame.color_jpeg.clear();
    frame.index = produced_;
    frame.capture_ns = options_.realtime ? instant : monotonic_ns();
    frame.device_ns = produced_ * period_ns;  // device clock: from its power-on
    frame.source_position = -1;
    ++produced_;
    return true;
}

}  // namespace rgbd::sensors
