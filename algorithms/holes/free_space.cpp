#include "algorithms/holes/free_space.hpp"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

#include "toolkit/error.hpp"
#include "toolkit/order_statistics.hpp"

namespace rgbd::holes {

void FreeSpaceOptions::check() const {
    check_range("free space: pixel", pixel, Range::closed(0.25, 20), "spacings");
    check_range("free space: margin", margin, Range::closed(0, 100), "spacings");
    check_range("free space: the facing angle", max_angle_deg, Range::open(0, 90), "degrees");
    check_range("free space: the background border", background_border, Range::closed(0, 1000),
                "pixels");
    check_range("free space: the background window", background_window, Range::closed(1, 50),
                "pixels");
}

namespace {
constexpr float kNone = std::numeric_limits<float>::infinity();
constexpr int kPad = 3;  // pixels around the points' bounding box

/// Depths [lo, hi] (along `forward` from `centre`) that hold the median depth of the points in
/// front with near certainty: the depths of ranks n/2 -+ 4 sqrt(n) of a sample of n >= 1000
/// (every k-th point, n about 32768): 8 standard deviations of the sample median's rank. The
/// caller then selects the median among the few depths inside (about 5% of the points, not
/// all of them: the selection was a quarter of the maps' cost on a 50-view sequence) and checks
/// that the median's rank falls there. The whole line (-inf, +inf) for fewer points.
std::pair<double, double> median_bracket(const std::vector<Eigen::Vector3d>& points,
                                         const Eigen::Vector3d& centre,
                                         const Eigen::Vector3d& forward,
                                         std::vector<double>& sample) {
    constexpr double kInf = std::numeric_limits<double>::infinity();
    const std::size_t stride = points.size() / 32768;
    if (stride < 2) return {-kInf, kInf};
    sample.clear();
    for (std::size_t i = 0; i < points.size(); i += stride) {
        const double z = (points[i] - centre).dot(forward);
        if (z > 0) sample.push_back(z);
    }
    if (sample.size() < 1000) return {-kInf, kInf};
    const std::size_t half = sample.size() / 2;
    const auto margin = static_cast<std::size_t>(4.0 * std::sqrt(double(sample.size())));
    const double lo = kth_smallest(sample, half - margin);
    return {lo, kth_smallest(sample, half + margin)};
}
}  // namespace

FreeSpace::FreeSpace(const std::vector<Eigen::Vector3d>& points,
                     const std::vector<SensorView>& sensors, double spacing_m,
                     const FreeSpaceOptions& options)
    : options_(options), spacing_(spacing_m) {
    options.check();
    RGBD_CHECK(std::isfinite(spacing_m) && spacing_m > 0,
               "free space: the spacing must be positive");
    if (points.empty()) return;
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const auto& p : points) centroid += p;
    centroid /= double(points.size());
    // One map per sensor, the sensors in parallel (each map is independent of the others; the
    // nearest depth per pixel is a minimum, so the order of the points does not matter), kept
    // in the sensors' order.
    std::vector<std::optional<Map>> built(sensors.size());
    // Per-thread projection buffers, allocated once (not once per sensor: 3 x 8 bytes per
    // point and sensor of zeroed, freshly faulted memory was most of this constructor).
    struct Buffers {
        std::vector<double> x, y, z, depths, sample;
    };
    tbb::enumerable_thread_specific<Buffers> buffers;
    tbb::parallel_for(std::size_t(0), sensors.size(), [&](std::size_t si) {
        const SensorView& s = sensors[si];
        Map m;
        m.sensor = s;
        m.sensor_from_world = s.world_from_sensor.inverse();
        m.centre = s.world_from_sensor.translation();
        const Eigen::Vector3d to_object = centroid - m.centre;
        if (to_object.norm() <= 0) return;
        m.forward = to_object.normalized();
        const Eigen::Vector3d seed =
            std::abs(m.forward.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitX();
        m.down = (seed - seed.dot(m.forward) * m.forward).normalized();
        m.right = m.down.cross(m.forward);
        // Image-plane coordinates (tan of the angle) and depth of every point in front.
        Buffers& buffer = buffers.local();
        buffer.x.resize(points.size());  // x, y are written where z > 0, read only there
        buffer.y.resize(points.size());
        buffer.z.resize(points.size());
        buffer.depths.clear();
        std::vector<double>&x = buffer.x, &y = buffer.y, &z = buffer.z, &depths = buffer.depths;
        const auto [lo, hi] = median_bracket(points, m.centre, m.forward, buffer.sample);
        double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
        std::size_t front = 0, below = 0;
        for (std::size_t i = 0; i < points.size(); ++i) {
            const Eigen::Vector3d d = points[i] - m.centre;
            z[i] = d.dot(m.forward);
            if (!(z[i] > 0)) continue;
            x[i] = d.dot(m.right) / z[i];
            y[i] = d.dot(m.down) / z[i];
            x0 = std::min(x0, x[i]), x1 = std::max(x1, x[i]);
            y0 = std::min(y0, y[i]), y1 = std::max(y1, y[i]);
            ++front;
            if (z[i] < lo)
                ++below;
            else if (z[i] <= hi)
                depths.push_back(z[i]);
        }
        if (front < 10) return;
        // The upper median of the depths in front (rank front / 2): within the bracket's
        // depths when its rank falls there, else (a bracket that missed) from all of them.
        const std::size_t rank = front / 2;
        if (rank < below || rank >= below + depths.size()) {
            depths.clear();
            for (std::size_t i = 0; i < points.size(); ++i)
                if (z[i] > 0) depths.push_back(z[i]);
            below = 0;
        }
        m.focal = kth_smallest(depths, rank - below) / (options.pixel * spacing_m);
        m.cols = static_cast<int>(std::ceil((x1 - x0) * m.focal)) + 1 + 2 * kPad;
        m.rows = static_cast<int>(std::ceil((y1 - y0) * m.focal)) + 1 + 2 * kPad;
        if (double(m.cols) * m.rows > 16e6) return;  // not an object in front of a sensor
        m.u0 = x0 - kPad / m.focal;
        m.v0 = y0 - kPad / m.focal;
        m.nearest.assign(std::size_t(m.cols) * m.rows, kNone);
        for (std::size_t i = 0; i < points.size(); ++i) {
            if (!(z[i] > 0)) continue;
            const int c = static_cast<int>((x[i] - m.u0) * m.focal);
            const int r = static_cast<int>((y[i] - m.v0) * m.focal);
            if (c < 0 || r < 0 || c >= m.cols || r >= m.rows) continue;
            const std::size_t k = std::size_t(r) * m.cols + c;
            m.nearest[k] = std::min(m.nearest[k], static_cast<float>(z[i]));
        }
        built[si] = std::move(m);
    });
    for (auto& m : built)
        if (m) maps_.push_back(std::move(*m));
}

int FreeSpace::seen_empty(const Eigen::Vector3d& p, const Eigen::Vector3d& n) const {
    return scan(p, n, false);
}

int FreeSpace::count_seen_empty(const Eigen::Vector3d& p, const Eigen::Vector3d& n) const {
    return scan(p, n, true);
}

int FreeSpace::scan(const Eigen::Vector3d& p, const Eigen::Vector3d& n, bool count) const {
    int hits = 0;
    const double cos_face = std::cos(options_.max_angle_deg * M_PI / 180.0);
    for (std::size_t s = 0; s < maps_.size(); ++s) {
        const Map& m = maps_[s];
        const Eigen::Vector3d d = p - m.centre;
        const double z = d.dot(m.forward);
        if (!(z > 0)) continue;
        if (m.sensor.intrinsics) {
            const Eigen::Vector3d c = m.sensor_from_world * p;
            if (c.z() <= 0) continue;
            const auto& k = *m.sensor.intrinsics;
            const double u = k.fx * c.x() / c.z() + k.cx, v = k.fy * c.y() / c.z() + k.cy;
            if (u < 0 || v < 0 || u > k.width - 1 || v > k.height - 1) continue;
        }
        const int c = static_cast<int>(std::floor((d.dot(m.right) / z - m.u0) * m.focal));
        const int r = static_cast<int>(std::floor((d.dot(m.down) / z - m.v0) * m.focal));
        if (c < 0 || r < 0 || c >= m.cols || r >= m.rows) continue;
        float near3 = kNone, near5 = kNone;
        const int w = options_.background_window;
        for (int dr = -w; dr <= w; ++dr)
            for (int dc = -w; dc <= w; ++dc) {
                const int r2 = r + dr, c2 = c + dc;
                if (r2 < 0 || c2 < 0 || r2 >= m.rows || c2 >= m.cols) continue;
                const float depth = m.nearest[std::size_t(r2) * m.cols + c2];
                near5 = std::min(near5, depth);
                if (std::abs(dr) <= 1 && std::abs(dc) <= 1) near3 = std::min(near3, depth);
            }
        if (near3 < kNone) {
            // Something measured in front of p (the view of it was blocked), or p on the
            // measured surface: no evidence. Everything behind by the margin: seen through,
            // when the sensor would have measured p's surface (facing it, not grazing).
            if (n.dot(-d.normalized()) >= cos_face && near3 > z + options_.margin * spacing_) {
                if (!count) return static_cast<int>(s);
                ++hits;
            }
            continue;
        }
        // Outside the silhouette of the measured object whatever p's normal: a point on the
        // object projects inside it from every sensor.
        // No return anywhere near the ray, well inside the sensor's view of the object.
        const int border = kPad + options_.background_border;
        if (options_.background && near5 == kNone && c >= border && r >= border &&
            c < m.cols - border && r < m.rows - border) {
            if (!count) return static_cast<int>(s);
            ++hits;
        }
    }
    return count ? hits : -1;
}

}  // namespace rgbd::holes
