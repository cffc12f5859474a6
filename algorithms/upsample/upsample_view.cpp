#include "algorithms/upsample/upsample_view.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "toolkit/error.hpp"

namespace rgbd::upsample {

void UpsampleOptions::check() const {
    RGBD_CHECK(neighbors == 4 || neighbors == 8, "upsample: neighbors must be 4 or 8");
    check_range("upsample: sigma_spatial", sigma_spatial, Range::open_closed(0.0, 10.0));
    check_range("upsample: sigma_color", sigma_color, Range::open_closed(0.0, 1000.0));
    check_range("upsample: theta_max_deg", theta_max_deg, Range::open(0.0, 90.0));
    check_range("upsample: sigma_factor", sigma_factor, Range::closed(0.0, 100.0));
    check_range("upsample: grazing_max_deg", grazing_max_deg, Range::open(0.0, 90.0));
    check_range("upsample: max_offset_factor", max_offset_factor, Range::open_closed(0.0, 10.0));
}

namespace {

std::string view_name(const PointCloud& cloud, const RgbdFrame& frame) {
    std::string name = "view " + std::to_string(cloud.view.id);
    if (!cloud.view.sensor.empty()) name += " of sensor " + cloud.view.sensor;
    const std::string& source = !cloud.view.source.empty() ? cloud.view.source : frame.source;
    if (!source.empty()) name += " (" + source + ")";
    return name;
}

/// Default axial noise model of docs/algorithms.md §4 (noise models), metres.
double default_sigma_z(double z) { return 0.0015 * (z / 1.5) * (z / 1.5); }

constexpr int kDu[8] = {1, -1, 0, 0, 1, -1, 1, -1};  // E W S N, then SE NW NE SW
constexpr int kDv[8] = {0, 0, 1, -1, 1, -1, -1, 1};
// Midpoints: E, S (4), + SE, SW (8): each grid edge is visited from one end only.
constexpr int kMu[4] = {1, 0, 1, -1};
constexpr int kMv[4] = {0, 1, 1, 1};

/// One new point before it goes into the point set.
struct Child {
    Eigen::Vector3d xyz;  // sensor frame
    Eigen::Vector3d normal;
    Rgb rgb;
    float confidence;
    std::uint32_t parent;  // index of the parent point
};

/// A depth sample of the parent's 3x3 neighbourhood (Algorithm A).
struct Sample {
    double u, v;  // colour-image position
    double h;     // offset of its plane along the parent normal, from the colour centre
    int rgb[3];
    std::int32_t index;
};

struct Counters {
    std::size_t parents = 0, gated = 0, uncoloured = 0, no_normal = 0, outside = 0, owned = 0,
                grazing = 0, offset = 0;
};

Rgb bgr_at(const cv::Mat& image, int u, int v) {
    const cv::Vec3b c = image.at<cv::Vec3b>(v, u);
    return {c[2], c[1], c[0]};
}

Rgb bilinear(const cv::Mat& image, double u, double v) {
    const int x0 = std::clamp(static_cast<int>(std::floor(u)), 0, image.cols - 1);
    const int y0 = std::clamp(static_cast<int>(std::floor(v)), 0, image.rows - 1);
    const int x1 = std::min(x0 + 1, image.cols - 1), y1 = std::min(y0 + 1, image.rows - 1);
    const double ax = std::clamp(u - x0, 0.0, 1.0), ay = std::clamp(v - y0, 0.0, 1.0);
    double acc[3] = {0, 0, 0};
    const int xs[2] = {x0, x1}, ys[2] = {y0, y1};
    for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
            const double w = (dx ? ax : 1.0 - ax) * (dy ? ay : 1.0 - ay);
            const cv::Vec3b c = image.at<cv::Vec3b>(ys[dy], xs[dx]);
            for (int k = 0; k < 3; ++k) acc[k] += w * c[2 - k];
        }
    auto to8 = [](double c) { return static_cast<std::uint8_t>(std::clamp(c + 0.5, 0.0, 255.0)); };
    return {to8(acc[0]), to8(acc[1]), to8(acc[2])};
}

/// The checked depth intrinsics of the view (the view's own, else the frame's depth camera's).
/// InputError naming the view when the view is not organised (grid, pixel property), the
/// frame has no 8-bit BGR colour image matching its intrinsics, an intrinsics is invalid, the
/// grid differs from the depth intrinsics, a world-frame view has no pose or color_from_depth
/// is not finite.
const PinholeIntrinsics& checked_depth_intrinsics(const PointCloud& cloud, const RgbdFrame& frame,
                                                  const std::string& name) {
    RGBD_CHECK(cloud.view.has_grid(),
               name +
                   ": the view has no pixel grid (rgbd:grid); super-resolution needs an "
                   "organised view as written by rgbd-cloud");
    RGBD_CHECK(cloud.pixel_map().has_value(), name + ": the view has no pixel property");
    RGBD_CHECK(!frame.color.empty(), name + ": the frame has no colour image");
    RGBD_CHECK(frame.color.type() == CV_8UC3, name + ": colour image must be CV_8UC3 BGR");
    const PinholeIntrinsics& kc = frame.color_intrinsics;
    const PinholeIntrinsics& kd =
        cloud.view.intrinsics ? *cloud.view.intrinsics : frame.depth_intrinsics;
    try {
        kc.check();
        kd.check();
    } catch (const InputError& e) {
        throw InputError(name + ": " + e.what());
    }
    RGBD_CHECK(frame.color.cols == kc.width && frame.color.rows == kc.height,
               name + ": colour image is " + std::to_string(frame.color.cols) + "x" +
                   std::to_string(frame.color.rows) + " but its intrinsics say " +
                   std::to_string(kc.width) + "x" + std::to_string(kc.height));
    RGBD_CHECK(cloud.view.grid_width == kd.width && cloud.view.grid_height == kd.height,
               name + ": the view grid differs from the depth intrinsics' size");
    RGBD_CHECK(cloud.view.frame != ViewFrame::kWorld || cloud.view.world_from_sensor.has_value(),
               name + ": the view is in the world frame but has no world_from_sensor pose");
    RGBD_CHECK(frame.color_from_depth.matrix().allFinite(),
               name + ": color_from_depth is not finite");
    return kd;
}

/// The view's measured points on the depth grid, in the sensor frame.
struct GridPoints {
    int width = 0, height = 0;
    std::vector<std::int32_t> grid;    ///< point index per depth pixel (-1 = no point)
    std::vector<Eigen::Vector3d> xyz;  ///< sensor-frame position
    std::vector<Eigen::Vector2d> uvc;  ///< colour-image projection
    std::vector<Rgb> rgb;              ///< the point's colour (its own, or the colour image's)
    std::vector<std::uint8_t> usable;  ///< 1 = on the grid, seen by the colour camera

    /// Point index at depth pixel (col, row); -1 outside the grid or without a point.
    std::int32_t at(int col, int row) const {
        if (col < 0 || row < 0 || col >= width || row >= height) return -1;
        return grid[static_cast<std::size_t>(row) * width + col];
    }
};

/// Per-point data of the view: the first non-synthetic point of every depth pixel goes on the
/// grid; its sensor-frame position, colour-image projection and colour (the view's own when
/// `has_colors`, else bilinear from the colour image) are taken when the colour camera sees it.
GridPoints grid_points(const PointCloud& cloud, const RgbdFrame& frame,
                       const Pose& sensor_from_view, bool has_colors) {
    const PinholeIntrinsics& kc = frame.color_intrinsics;
    const std::size_t n = cloud.size();
    const auto pixel_map = cloud.pixel_map();
    const auto synthetic = cloud.flag(prop::kSynthetic);
    const auto uncoloured_map = cloud.flag("uncoloured");
    std::optional<PointCloud::ColorMaps> colors;
    if (has_colors) colors = cloud.colors();
    GridPoints g;
    g.width = cloud.view.grid_width;
    g.height = cloud.view.grid_height;
    g.grid.assign(static_cast<std::size_t>(g.width) * g.height, -1);
    g.xyz.resize(n);
    g.uvc.resize(n);
    g.rgb.resize(n);
    g.usable.assign(n, 0);
    for (std::size_t i = 0; i < n; ++i) {
        const PointSet::Index idx(i);
        if (synthetic && (*synthetic)[idx]) continue;
        const std::uint32_t pix = (*pixel_map)[idx];
        if (pix >= g.grid.size()) continue;
        if (g.grid[pix] < 0) g.grid[pix] = static_cast<std::int32_t>(i);
    }
    const Pose& c_from_d = frame.color_from_depth;
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, n, 4096), [&](const tbb::blocked_range<std::size_t>& r) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                const PointSet::Index idx(i);
                const std::uint32_t pix = (*pixel_map)[idx];
                if (pix >= g.grid.size() || g.grid[pix] != static_cast<std::int32_t>(i)) continue;
                g.xyz[i] = sensor_from_view * to_eigen(cloud.points.point(idx));
                const Eigen::Vector3d pc = c_from_d * g.xyz[i];
                if (!(g.xyz[i].z() > 0.0) || !(pc.z() > 0.0)) continue;
                g.uvc[i] = kc.project(pc);
                if (!std::isfinite(g.uvc[i].x()) || !std::isfinite(g.uvc[i].y()) ||
                    !kc.contains(g.uvc[i]))
                    continue;
                if (uncoloured_map && (*uncoloured_map)[idx]) continue;
                g.rgb[i] = has_colors ? colors->get(idx)
                                      : bilinear(frame.color, g.uvc[i].x(), g.uvc[i].y());
                g.usable[i] = 1;
            }
        });
    return g;
}

/// Geometry of the colour camera in the depth frame, the colour-pixel steps and the gates.
struct ColourGeometry {
    Eigen::Matrix3d r_dc;    ///< depth_from_color rotation
    Eigen::Vector3d origin;  ///< colour camera centre in the depth frame
    bool distorted = false;
    double rho_u = 0, rho_v = 0, rho = 0;  ///< colour / depth focal lengths
    double step_u = 0, step_v = 0;         ///< colour-pixel steps of a child, rho / 3
    bool integer_steps = false;            ///< steps of whole colour pixels
    int istep_u = 0, istep_v = 0;
    double tan_theta = 0, cos2_grazing = 0, max_offset2 = 0;
    /// Undistorted colour ray through pixel (u, v), in the depth frame: ray0 + u ray_du + v ray_dv.
    Eigen::Vector3d ray_du, ray_dv, ray0;
};

/// The colour camera's geometry relative to depth camera `kd` and the options' gates.
ColourGeometry colour_geometry(const RgbdFrame& frame, const PinholeIntrinsics& kd,
                               const UpsampleOptions& options) {
    const PinholeIntrinsics& kc = frame.color_intrinsics;
    const Pose& c_from_d = frame.color_from_depth;
    ColourGeometry g;
    g.r_dc = c_from_d.linear().transpose();
    g.origin = -(g.r_dc * c_from_d.translation());
    g.distorted = !kc.distortion.is_none();
    g.rho_u = kc.fx / kd.fx;
    g.rho_v = kc.fy / kd.fy;
    g.rho = 0.5 * (g.rho_u + g.rho_v);
    g.step_u = g.rho_u / 3.0;
    g.step_v = g.rho_v / 3.0;
    g.integer_steps = g.step_u >= 0.75 && g.step_v >= 0.75;
    g.istep_u = static_cast<int>(std::lround(g.step_u));
    g.istep_v = static_cast<int>(std::lround(g.step_v));
    g.tan_theta = std::tan(options.theta_max_deg * M_PI / 180.0);
    const double cos_grazing = std::cos(options.grazing_max_deg * M_PI / 180.0);
    g.cos2_grazing = cos_grazing * cos_grazing;
    g.max_offset2 = options.max_offset_factor * options.max_offset_factor;
    g.ray_du = g.r_dc.col(0) / kc.fx;
    g.ray_dv = g.r_dc.col(1) / kc.fy;
    g.ray0 = g.r_dc.col(2) - kc.cx * g.ray_du - kc.cy * g.ray_dv;
    return g;
}

constexpr int kSpatialBins = 4096;
constexpr double kSpatialStep = 8.0;  // bins per px^2

/// Kernel look-up tables of the joint bilateral weight: spatial on the squared colour-pixel
/// distance (1/8 px^2 steps, sigma_s colour pixels), range on the mean absolute RGB difference
/// (integer levels).
struct Kernels {
    std::array<float, kSpatialBins> spatial;
    std::array<float, 256> range;
};

/// The look-up tables for spatial sigma `sigma_s` (colour pixels) and colour sigma `sigma_color`.
Kernels bilateral_kernels(double sigma_s, double sigma_color) {
    Kernels k;
    for (int b = 0; b < kSpatialBins; ++b)
        k.spatial[b] =
            static_cast<float>(std::exp(-(b / kSpatialStep) / (2.0 * sigma_s * sigma_s)));
    for (int b = 0; b < 256; ++b)
        k.range[b] = static_cast<float>(std::exp(-(b * b) / (2.0 * sigma_color * sigma_color)));
    return k;
}

/// The children of the view's depth points, row by row (docs/algorithms.md §5): reads the grid
/// points, the colour image and the geometry, shared by all rows.
class ChildMaker {
public:
    ChildMaker(const GridPoints& g, const RgbdFrame& frame, const PinholeIntrinsics& kd,
               const ColourGeometry& geo, const Kernels& kernels, const UpsampleOptions& options,
               const std::optional<PointCloud::FloatMap>& confidence_map)
        : g_(g),
          frame_(frame),
          kc_(frame.color_intrinsics),
          kd_(kd),
          geo_(geo),
          kernels_(kernels),
          options_(options),
          confidence_map_(confidence_map),
          midpoints_(options.method == UpsampleMethod::kMidpoints),
          k_children_(midpoints_ ? options.neighbors / 2 : options.neighbors) {}

    /// New points per depth point at most.
    int children_per_point() const { return k_children_; }

    /// Appends the children of the depth points of `row` to `out` and counts the outcomes.
    void row(int row, std::vector<Child>& out, Counters& count) const {
        for (int col = 0; col < g_.width; ++col) {
            const std::int32_t ip = g_.at(col, row);
            if (ip < 0 || !g_.usable[ip]) {
                if (ip >= 0) ++count.uncoloured;
                continue;
            }
            const Eigen::Vector3d& xp = g_.xyz[ip];
            const double z = xp.z();
            const double s_d = z / kd_.fx;
            const double dz_max = s_d * geo_.tan_theta + options_.sigma_factor * default_sigma_z(z);
            if (at_discontinuity(col, row, z, dz_max)) {
                ++count.gated;
                continue;
            }
            ++count.parents;
            const float parent_conf = confidence(ip);
            Eigen::Vector3d normal;
            const double nn = grid_normal(col, row, xp, normal);
            if (midpoints_) {
                midpoint_children(col, row, ip, z, dz_max, normal, parent_conf, out, count);
                continue;
            }
            if (!(nn > 0.0)) {
                ++count.no_normal;
                continue;
            }
            colour_pixel_children(col, row, ip, s_d, normal, parent_conf, out, count);
        }
    }

private:
    /// The point's confidence (1 without a confidence property).
    float confidence(std::int32_t i) const {
        return confidence_map_ ? (*confidence_map_)[PointSet::Index(i)] : 1.0f;
    }

    /// The gate: true unless every existing 8-neighbour of (col, row) is coloured and within
    /// dz_max of depth z (on the same surface).
    bool at_discontinuity(int col, int row, double z, double dz_max) const {
        bool gated = false;
        for (int k = 0; k < 8 && !gated; ++k) {
            const std::int32_t j = g_.at(col + kDu[k], row + kDv[k]);
            if (j < 0) continue;
            gated = !g_.usable[j] || std::abs(g_.xyz[j].z() - z) > dz_max;
        }
        return gated;
    }

    /// The unit normal at (col, row) (point xp) from the grid, facing the camera: the cross
    /// product of central differences, one-sided at borders; zero when a direction has no
    /// neighbour. Returns the cross product's norm (0: no normal).
    double grid_normal(int col, int row, const Eigen::Vector3d& xp, Eigen::Vector3d& normal) const {
        auto diff = [&](int du, int dv, Eigen::Vector3d& d) {
            const std::int32_t a = g_.at(col + du, row + dv), b = g_.at(col - du, row - dv);
            if (a >= 0 && b >= 0)
                d = g_.xyz[a] - g_.xyz[b];
            else if (a >= 0)
                d = g_.xyz[a] - xp;
            else if (b >= 0)
                d = xp - g_.xyz[b];
            else
                return false;
            return true;
        };
        Eigen::Vector3d dx, dy;
        normal = Eigen::Vector3d::Zero();
        if (diff(1, 0, dx) && diff(0, 1, dy)) normal = dx.cross(dy);
        const double nn = normal.norm();
        if (nn > 0.0) {
            normal /= nn;
            if (normal.dot(xp) > 0.0) normal = -normal;
        }
        return nn;
    }

    /// Algorithm B: midpoints of the grid edges from parent ip at (col, row) (depth z) to its
    /// E, S (+ SE, SW) neighbours on the same surface, coloured bilinearly.
    void midpoint_children(int col, int row, std::int32_t ip, double z, double dz_max,
                           const Eigen::Vector3d& normal, float parent_conf,
                           std::vector<Child>& out, Counters& count) const {
        const Eigen::Vector3d& xp = g_.xyz[ip];
        for (int k = 0; k < k_children_; ++k) {
            const std::int32_t j = g_.at(col + kMu[k], row + kMv[k]);
            if (j < 0 || !g_.usable[j] || std::abs(g_.xyz[j].z() - z) > dz_max) continue;
            const Eigen::Vector3d m = 0.5 * (xp + g_.xyz[j]);
            const Eigen::Vector2d q = kc_.project(frame_.color_from_depth * m);
            if (!kc_.contains(q)) {
                ++count.outside;
                continue;
            }
            out.push_back({m, normal, bilinear(frame_.color, q.x(), q.y()),
                           0.8f * std::min(parent_conf, confidence(j)),
                           static_cast<std::uint32_t>(ip)});
        }
    }

    /// Algorithm A: new points at the colour pixels around parent ip's colour pixel. The 3x3
    /// depth neighbourhood (all usable: the gate passed) is gathered once per parent: its
    /// colour-image position, colour and the offset of its plane along the normal.
    void colour_pixel_children(int col, int row, std::int32_t ip, double s_d,
                               const Eigen::Vector3d& normal, float parent_conf,
                               std::vector<Child>& out, Counters& count) const {
        std::array<Sample, 9> nb;
        int m = 0;
        for (int dv = -1; dv <= 1; ++dv)
            for (int du = -1; du <= 1; ++du) {
                const std::int32_t j = g_.at(col + du, row + dv);
                if (j < 0) continue;
                nb[m++] = {g_.uvc[j].x(),
                           g_.uvc[j].y(),
                           normal.dot(g_.xyz[j] - geo_.origin),
                           {g_.rgb[j].r, g_.rgb[j].g, g_.rgb[j].b},
                           j};
            }
        const Eigen::Vector2d& q0 = g_.uvc[ip];
        const double c0u = std::round(q0.x()), c0v = std::round(q0.y());
        for (int k = 0; k < k_children_; ++k) {
            const double qu =
                geo_.integer_steps ? c0u + kDu[k] * geo_.istep_u : q0.x() + kDu[k] * geo_.step_u;
            const double qv =
                geo_.integer_steps ? c0v + kDv[k] * geo_.istep_v : q0.y() + kDv[k] * geo_.step_v;
            colour_pixel_child(qu, qv, ip, s_d, normal, parent_conf, nb, m, out, count);
        }
    }

    /// One child of Algorithm A at colour pixel (qu, qv), unless rejected (and counted): outside
    /// the image, owned by a nearer neighbour's projection, seen at a grazing angle, or placed
    /// behind the camera or farther than max_offset_factor pixel footprints s_d from its parent.
    /// Its depth is the joint bilateral average of the plane offsets of the m samples `nb`.
    void colour_pixel_child(double qu, double qv, std::int32_t ip, double s_d,
                            const Eigen::Vector3d& normal, float parent_conf,
                            const std::array<Sample, 9>& nb, int m, std::vector<Child>& out,
                            Counters& count) const {
        const Eigen::Vector3d& xp = g_.xyz[ip];
        const Eigen::Vector2d& q0 = g_.uvc[ip];
        if (qu < 0.0 || qv < 0.0 || qu > kc_.width - 1 || qv > kc_.height - 1) {
            ++count.outside;
            return;
        }
        // Ownership first: the colour pixel belongs to the nearest projection.
        const double d2p = (q0.x() - qu) * (q0.x() - qu) + (q0.y() - qv) * (q0.y() - qv);
        double d2s[9];
        for (int a = 0; a < m; ++a) {
            const double eu = nb[a].u - qu, ev = nb[a].v - qv;
            d2s[a] = eu * eu + ev * ev;
            if (nb[a].index != ip && (d2s[a] < d2p || (d2s[a] == d2p && nb[a].index < ip))) {
                ++count.owned;
                return;
            }
        }
        // Ray of the colour pixel, in the depth frame.
        const Eigen::Vector3d ray =
            geo_.distorted ? Eigen::Vector3d(geo_.r_dc * kc_.unproject(qu, qv, 1.0))
                           : Eigen::Vector3d(geo_.ray0 + qu * geo_.ray_du + qv * geo_.ray_dv);
        const double nr = normal.dot(ray);
        if (nr * nr < geo_.cos2_grazing * ray.squaredNorm()) {
            ++count.grazing;
            return;
        }
        const Rgb cq = geo_.integer_steps
                           ? bgr_at(frame_.color, static_cast<int>(qu), static_cast<int>(qv))
                           : bilinear(frame_.color, qu, qv);
        // Joint bilateral average of the plane offsets over the 3x3 samples.
        double wsum = 0.0, wssum = 0.0, hsum = 0.0;
        for (int a = 0; a < m; ++a) {
            const int sb = std::min(kSpatialBins - 1, static_cast<int>(d2s[a] * kSpatialStep));
            const int dc =
                (std::abs(int(cq.r) - nb[a].rgb[0]) + std::abs(int(cq.g) - nb[a].rgb[1]) +
                 std::abs(int(cq.b) - nb[a].rgb[2]) + 1) /
                3;
            const double ws = kernels_.spatial[sb];
            const double w = ws * kernels_.range[std::min(dc, 255)];
            hsum += w * nb[a].h;
            wsum += w;
            wssum += ws;
        }
        // Colour unlike every sample: fall back to the parent's plane.
        const double h_parent = normal.dot(xp - geo_.origin);
        const double t = wsum > 1e-12 ? hsum / (wsum * nr) : h_parent / nr;
        const Eigen::Vector3d y = geo_.origin + t * ray;
        if (!(t > 0.0) || (y - xp).squaredNorm() > geo_.max_offset2 * s_d * s_d) {
            ++count.offset;
            return;
        }
        const double colour_weight = std::min(1.0, (wsum > 1e-12 ? wsum : 1.0) / wssum);
        out.push_back({y, normal, cq, static_cast<float>(parent_conf * colour_weight),
                       static_cast<std::uint32_t>(ip)});
    }

    const GridPoints& g_;
    const RgbdFrame& frame_;
    const PinholeIntrinsics& kc_;
    const PinholeIntrinsics& kd_;
    const ColourGeometry& geo_;
    const Kernels& kernels_;
    const UpsampleOptions& options_;
    const std::optional<PointCloud::FloatMap>& confidence_map_;
    const bool midpoints_;
    const int k_children_;
};

/// Appends the children to the cloud in row order (deterministic), in the view's frame: colour,
/// synthetic flag, colour_pixel flag (`colour_pixels`: their colour is their colour pixel's),
/// confidence, the parent's pixel and view id, and a normal facing the parent's
/// when the cloud has normals. A cloud without colours first gets the grid points' colours.
/// Returns the number added.
std::size_t append_children(PointCloud& cloud, const std::vector<std::vector<Child>>& row_children,
                            const GridPoints& g, bool has_colors, bool colour_pixels,
                            const Pose& view_from_sensor) {
    const std::size_t n = cloud.size();
    const int height = g.height;
    std::vector<std::size_t> row_offset(height + 1, n);
    for (int row = 0; row < height; ++row)
        row_offset[row + 1] = row_offset[row] + row_children[row].size();
    const std::size_t added = row_offset[height] - n;
    auto new_colors = cloud.add_colors();
    if (!has_colors) {
        for (std::size_t i = 0; i < n; ++i)
            if (g.usable[i]) new_colors.set(PointSet::Index(i), g.rgb[i]);
    }
    auto flag = cloud.add_flag(prop::kSynthetic);
    auto colour_pixel = cloud.add_flag(prop::kColourPixel);
    auto confidence = cloud.add_float(prop::kConfidence, 1.0f);
    auto pixels = cloud.add_pixel_map();
    const auto view_ids = cloud.view_map();
    const bool normals = cloud.points.has_normal_map();
    cloud.points.resize(n + added);
    tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& r) {
        for (int row = r.begin(); row != r.end(); ++row) {
            std::size_t o = row_offset[row];
            for (const Child& c : row_children[row]) {
                const PointSet::Index idx(o++);
                const PointSet::Index parent(c.parent);
                cloud.points.point(idx) = to_point(view_from_sensor * c.xyz);
                if (normals) {
                    Eigen::Vector3d nv = view_from_sensor.linear() * c.normal;
                    if (nv.dot(to_eigen(cloud.points.normal(parent))) < 0.0) nv = -nv;
                    cloud.points.normal(idx) = Vector_3(nv.x(), nv.y(), nv.z());
                }
                new_colors.set(idx, c.rgb);
                flag[idx] = 1;
                colour_pixel[idx] = colour_pixels ? 1 : 0;
                confidence[idx] = c.confidence;
                pixels[idx] = pixels[parent];
                if (view_ids) (*view_ids)[idx] = (*view_ids)[parent];
            }
        }
    });
    return added;
}

/// The sum of the rows' counters.
Counters sum_counts(const std::vector<Counters>& row_counts) {
    Counters total;
    for (const Counters& c : row_counts) {
        total.parents += c.parents;
        total.gated += c.gated;
        total.uncoloured += c.uncoloured;
        total.no_normal += c.no_normal;
        total.outside += c.outside;
        total.owned += c.owned;
        total.grazing += c.grazing;
        total.offset += c.offset;
    }
    return total;
}

}  // namespace

Report upsample_view(PointCloud& cloud, const RgbdFrame& frame, const UpsampleOptions& options,
                     const Progress& progress) {
    Stopwatch watch;
    options.check();
    const std::string name = view_name(cloud, frame);
    const PinholeIntrinsics& kd = checked_depth_intrinsics(cloud, frame, name);
    const bool world = cloud.view.frame == ViewFrame::kWorld;
    if (cloud.points.has_garbage()) cloud.points.collect_garbage();

    const int height = cloud.view.grid_height;
    const std::size_t n = cloud.size();
    const Pose sensor_from_view =
        world ? Pose(cloud.view.world_from_sensor->inverse()) : Pose(Pose::Identity());
    const auto confidence_map = cloud.float_map(prop::kConfidence);
    const bool has_colors = cloud.has_colors();
    const GridPoints g = grid_points(cloud, frame, sensor_from_view, has_colors);
    const double time_prepare_s = watch.seconds();
    if (!report_progress(progress, 0.2)) throw AlgorithmError(name + ": upsample cancelled");

    const ColourGeometry geo = colour_geometry(frame, kd, options);
    const Kernels kernels = bilateral_kernels(options.sigma_spatial * geo.rho, options.sigma_color);
    const ChildMaker maker(g, frame, kd, geo, kernels, options, confidence_map);

    // Children per row (capacity reserved up front: no allocation in the inner loop).
    std::vector<std::vector<Child>> row_children(height);
    std::vector<Counters> row_counts(height);
    std::vector<std::uint32_t> row_points(height, 0);
    for (std::size_t pix = 0; pix < g.grid.size(); ++pix)
        if (g.grid[pix] >= 0) ++row_points[pix / g.width];
    tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& r) {
        for (int row = r.begin(); row != r.end(); ++row) {
            row_children[row].reserve(static_cast<std::size_t>(row_points[row]) *
                                      maker.children_per_point());
            maker.row(row, row_children[row], row_counts[row]);
        }
    });
    const double time_children_s = watch.seconds() - time_prepare_s;
    if (!report_progress(progress, 0.8)) throw AlgorithmError(name + ": upsample cancelled");

    const Pose view_from_sensor = world ? *cloud.view.world_from_sensor : Pose(Pose::Identity());
    const std::size_t added =
        append_children(cloud, row_children, g, has_colors,
                        options.method != UpsampleMethod::kMidpoints, view_from_sensor);

    const Counters total = sum_counts(row_counts);
    Report report;
    report["method"] = options.method == UpsampleMethod::kMidpoints ? "midpoints" : "colour_pixels";
    report["neighbors"] = options.neighbors;
    report["rho"] = geo.rho;
    report["colour_steps"] = geo.integer_steps ? "pixels" : "sub_pixel";
    report["points_before"] = n;
    report["points_after"] = cloud.size();
    report["added"] = added;
    report["ratio"] = n > 0 ? static_cast<double>(cloud.size()) / static_cast<double>(n) : 0.0;
    report["parents"] = total.parents;
    report["gated_discontinuity"] = total.gated;
    report["not_coloured"] = total.uncoloured;
    report["no_normal"] = total.no_normal;
    report["rejected_outside"] = total.outside;
    report["rejected_owned_by_neighbour"] = total.owned;
    report["rejected_grazing"] = total.grazing;
    report["rejected_offset"] = total.offset;
    report["time_s"] = watch.seconds();
    report["time_prepare_s"] = time_prepare_s;
    report["time_children_s"] = time_children_s;
    report["time_append_s"] = watch.seconds() - time_prepare_s - time_children_s;
    report_progress(progress, 1.0);
    return report;
}

}  // namespace rgbd::upsample
