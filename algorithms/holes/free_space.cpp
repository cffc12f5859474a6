#include "algorithms/holes/free_space.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
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

namespace {

/// Points per step of a map's passes (the step's projections stay in the first-level cache).
constexpr std::size_t kStep = 2048;

/// The points relative to their centroid, in single precision, one array per axis: the maps'
/// passes read 12 bytes per point instead of 24 and project 4 or 8 at a time (the depths are
/// kept as float anyway; a metre-sized scene loses under a micrometre).
struct PointArrays {
    std::vector<float> x, y, z;
};

/// Depth along f and image-plane coordinates (tan of the angle: along r and d over the
/// depth) of the points [0, n) of (X, Y, Z) seen from c, into (z, x, y); x and y are
/// meaningless where z <= 0 (behind the sensor).
void project_step(const float* __restrict X, const float* __restrict Y, const float* __restrict Z,
                  std::size_t n, const std::array<float, 3>& c, const std::array<float, 3>& f,
                  const std::array<float, 3>& r, const std::array<float, 3>& d, float* __restrict z,
                  float* __restrict x, float* __restrict y) {
    const float c0 = c[0], c1 = c[1], c2 = c[2], f0 = f[0], f1 = f[1], f2 = f[2];
    const float r0 = r[0], r1 = r[1], r2 = r[2], d0 = d[0], d1 = d[1], d2 = d[2];
    for (std::size_t i = 0; i < n; ++i) {
        const float dx = X[i] - c0, dy = Y[i] - c1, dz = Z[i] - c2;
        const float depth = dx * f0 + dy * f1 + dz * f2;
        const float inv = 1.0f / depth;
        z[i] = depth;
        x[i] = (dx * r0 + dy * r1 + dz * r2) * inv;
        y[i] = (dx * d0 + dy * d1 + dz * d2) * inv;
    }
}

/// Grows box = {x0, x1, y0, y1} by the coordinates (x, y) of the points [0, n) in front (z > 0).
__attribute__((noinline)) void extend_box(const float* __restrict z, const float* __restrict x,
                                          const float* __restrict y, std::size_t n,
                                          std::array<float, 4>& box) {
    float x0 = box[0], x1 = box[1], y0 = box[2], y1 = box[3];
    for (std::size_t i = 0; i < n; ++i) {
        if (!(z[i] > 0)) continue;
        x0 = x[i] < x0 ? x[i] : x0, x1 = x[i] > x1 ? x[i] : x1;
        y0 = y[i] < y0 ? y[i] : y0, y1 = y[i] > y1 ? y[i] : y1;
    }
    box = {x0, x1, y0, y1};
}

/// Projects the points of `rel` step by step (project_step, seen from c with axes f, r, d) into
/// the buffers z, x, y of kStep floats, and calls visit(count) after each step's `count` points.
template <typename Visit>
void for_each_step(const PointArrays& rel, const std::array<float, 3>& c,
                   const std::array<float, 3>& f, const std::array<float, 3>& r,
                   const std::array<float, 3>& d, float* z, float* x, float* y, Visit&& visit) {
    const std::size_t n = rel.x.size();
    for (std::size_t begin = 0; begin < n; begin += kStep) {
        const std::size_t count = std::min(kStep, n - begin);
        project_step(&rel.x[begin], &rel.y[begin], &rel.z[begin], count, c, f, r, d, z, x, y);
        visit(count);
    }
}

std::array<float, 3> to_float(const Eigen::Vector3d& v) {
    return {static_cast<float>(v.x()), static_cast<float>(v.y()), static_cast<float>(v.z())};
}

}  // namespace

FreeSpace::FreeSpace(const std::vector<Eigen::Vector3d>& points,
                     const std::vector<SensorView>& sensors, double spacing_m,
                     const FreeSpaceOptions& options, const std::vector<Eigen::Vector3d>& evidence)
    : options_(options), spacing_(spacing_m) {
    options.check();
    RGBD_CHECK(std::isfinite(spacing_m) && spacing_m > 0,
               "free space: the spacing must be positive");
    if (points.empty()) return;
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const auto& p : points) centroid += p;
    centroid /= double(points.size());
    PointArrays rel;
    const auto relative = [&centroid](const std::vector<Eigen::Vector3d>& from, PointArrays& to) {
        const std::size_t count = from.size();
        to.x.resize(count), to.y.resize(count), to.z.resize(count);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, 16384), [&](const auto& range) {
            for (std::size_t i = range.begin(); i != range.end(); ++i) {
                const Eigen::Vector3d q = from[i] - centroid;
                to.x[i] = static_cast<float>(q.x());
                to.y[i] = static_cast<float>(q.y());
                to.z[i] = static_cast<float>(q.z());
            }
        });
    };
    relative(points, rel);
    PointArrays more;  // the evidence, in the same frame
    relative(evidence, more);
    // One map per sensor, the sensors in parallel (each map is independent of the others; the
    // nearest depth per pixel is a minimum, so the order of the points does not matter), kept
    // in the sensors' order. A sensor's two passes go over all the points while its map (a
    // few MB) stays in the core's cache.
    std::vector<std::optional<Map>> built(sensors.size());
    struct Buffers {  // per thread, allocated once
        std::vector<float> z = std::vector<float>(kStep), x = z, y = z;
        std::vector<double> depths, sample;
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
        const std::array<float, 3> c = to_float(m.centre - centroid), f = to_float(m.forward),
                                   r = to_float(m.right), d = to_float(m.down);
        Buffers& buffer = buffers.local();
        float *z = buffer.z.data(), *x = buffer.x.data(), *y = buffer.y.data();
        std::vector<double>& depths = buffer.depths;
        depths.clear();
        // First pass: the image-plane bounding box of the points in front and their depths
        // near the median (median_bracket()).
        const auto [lo, hi] = median_bracket(points, m.centre, m.forward, buffer.sample);
        std::array<float, 4> box = {
            std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
            std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity()};
        std::size_t front = 0, below = 0;
        const float lo_f = static_cast<float>(lo), hi_f = static_cast<float>(hi);
        for_each_step(rel, c, f, r, d, z, x, y, [&](std::size_t count) {
            extend_box(z, x, y, count, box);
            for (std::size_t i = 0; i < count; ++i) {
                const float zi = z[i];
                if (!(zi > 0)) continue;
                ++front;
                if (zi < lo_f)
                    ++below;
                else if (zi <= hi_f)
                    depths.push_back(zi);
            }
        });
        const float x0 = box[0], x1 = box[1], y0 = box[2], y1 = box[3];
        if (front < 10) return;
        // The upper median of the depths in front (rank front / 2): within the bracket's
        // depths when its rank falls there, else (a bracket that missed) from all of them.
        const std::size_t rank = front / 2;
        if (rank < below || rank >= below + depths.size()) {
            depths.clear();
            for_each_step(rel, c, f, r, d, z, x, y, [&](std::size_t count) {
                for (std::size_t i = 0; i < count; ++i)
                    if (z[i] > 0) depths.push_back(z[i]);
            });
            below = 0;
        }
        m.focal = kth_smallest(depths, rank - below) / (options.pixel * spacing_m);
        m.inner_cols = static_cast<int>(std::ceil((x1 - x0) * m.focal)) + 1 + 2 * kPad;
        m.inner_rows = static_cast<int>(std::ceil((y1 - y0) * m.focal)) + 1 + 2 * kPad;
        if (double(m.inner_cols) * m.inner_rows > 16e6)
            return;  // not an object in front of a sensor
        // The evidence's box, in whole pixels beyond the points' own, at most half the points'
        // width (height) on each side.
        std::array<float, 4> wide = box;
        for_each_step(more, c, f, r, d, z, x, y,
                      [&](std::size_t count) { extend_box(z, x, y, count, wide); });
        const auto grow = [&m](float beyond, int limit) {
            const double pixels = std::ceil(std::max(0.0f, beyond) * m.focal);
            return static_cast<int>(std::min(pixels, double(limit / 2)));
        };
        const int left = grow(x0 - wide[0], m.inner_cols), right = grow(wide[1] - x1, m.inner_cols);
        const int top = grow(y0 - wide[2], m.inner_rows), bottom = grow(wide[3] - y1, m.inner_rows);
        m.col0 = left, m.row0 = top;
        m.cols = m.inner_cols + left + right;
        m.rows = m.inner_rows + top + bottom;
        if (double(m.cols) * m.rows > 16e6) return;
        m.u0 = x0 - (kPad + left) / m.focal;
        m.v0 = y0 - (kPad + top) / m.focal;
        m.nearest.assign(std::size_t(m.cols) * m.rows, kNone);
        if (!more.x.empty()) m.evidence.assign(m.nearest.size(), kNone);
        // Second pass: the nearest depth per pixel, of the points and of the evidence.
        const float u0 = static_cast<float>(m.u0), v0 = static_cast<float>(m.v0),
                    focal = static_cast<float>(m.focal);
        const auto splat_into = [&](std::vector<float>& image) {
            return [&](std::size_t count) {
                for (std::size_t i = 0; i < count; ++i) {
                    if (!(z[i] > 0)) continue;
                    const int col = static_cast<int>((x[i] - u0) * focal);
                    const int row = static_cast<int>((y[i] - v0) * focal);
                    if (col < 0 || row < 0 || col >= m.cols || row >= m.rows) continue;
                    float& nearest = image[std::size_t(row) * m.cols + col];
                    nearest = std::min(nearest, z[i]);
                }
            };
        };
        for_each_step(rel, c, f, r, d, z, x, y, splat_into(m.nearest));
        if (!more.x.empty()) for_each_step(more, c, f, r, d, z, x, y, splat_into(m.evidence));
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
        float near3 = kNone, near5 = kNone, more3 = kNone;
        const int w = options_.background_window;
        for (int dr = -w; dr <= w; ++dr)
            for (int dc = -w; dc <= w; ++dc) {
                const int r2 = r + dr, c2 = c + dc;
                if (r2 < 0 || c2 < 0 || r2 >= m.rows || c2 >= m.cols) continue;
                const std::size_t at = std::size_t(r2) * m.cols + c2;
                const float depth = m.nearest[at];
                near5 = std::min(near5, depth);
                if (std::abs(dr) <= 1 && std::abs(dc) <= 1) {
                    near3 = std::min(near3, depth);
                    if (!m.evidence.empty()) more3 = std::min(more3, m.evidence[at]);
                }
            }
        const double behind = z + options_.margin * spacing_;
        if (near3 < kNone) {
            // Something measured in front of p (the view of it was blocked), or p on the
            // measured surface: no evidence. Everything behind by the margin: seen through,
            // when the sensor would have measured p's surface (facing it, not grazing).
            if (n.dot(-d.normalized()) >= cos_face && std::min(near3, more3) > behind) {
                if (!count) return static_cast<int>(s);
                ++hits;
            }
            continue;
        }
        if (near5 == kNone && more3 < kNone) {
            // Outside the object's silhouette, the sensor measured something else (the floor
            // beside the object): seen through whatever p's normal when it lies behind p, no
            // evidence when it lies in front (clutter before p).
            if (more3 > behind) {
                if (!count) return static_cast<int>(s);
                ++hits;
            }
            continue;
        }
        // Outside the silhouette of the measured object whatever p's normal: a point on the
        // object projects inside it from every sensor.
        // No return anywhere near the ray, well inside the sensor's view of the object.
        const int border = kPad + options_.background_border;
        const int ci = c - m.col0, ri = r - m.row0;  // in the points' own frame
        if (options_.background && near5 == kNone && ci >= border && ri >= border &&
            ci < m.inner_cols - border && ri < m.inner_rows - border) {
            if (!count) return static_cast<int>(s);
            ++hits;
        }
    }
    return count ? hits : -1;
}

}  // namespace rgbd::holes
