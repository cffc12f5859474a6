#include "algorithms/upsample/upsample_view.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
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

}  // namespace

Report upsample_view(PointCloud& cloud, const RgbdFrame& frame, const UpsampleOptions& options,
                     const Progress& progress) {
    Stopwatch watch;
    options.check();
    const std::string name = view_name(cloud, frame);
    RGBD_CHECK(cloud.view.has_grid(),
               name +
                   ": the view has no pixel grid (rgbd:grid); super-resolution needs an "
                   "organised view as written by rgbd-cloud");
    const auto pixel_map = cloud.pixel_map();
    RGBD_CHECK(pixel_map.has_value(), name + ": the view has no pixel property");
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
    const bool world = cloud.view.frame == ViewFrame::kWorld;
    RGBD_CHECK(!world || cloud.view.world_from_sensor.has_value(),
               name + ": the view is in the world frame but has no world_from_sensor pose");
    RGBD_CHECK(frame.color_from_depth.matrix().allFinite(),
               name + ": color_from_depth is not finite");
    if (cloud.points.has_garbage()) cloud.points.collect_garbage();

    const int width = cloud.view.grid_width, height = cloud.view.grid_height;
    const std::size_t n = cloud.size();
    const Pose sensor_from_view =
        world ? Pose(cloud.view.world_from_sensor->inverse()) : Pose(Pose::Identity());

    // Per-point data: sensor-frame position, colour, colour-image projection; dense grid of
    // point indices (-1 = no point).
    const auto synthetic = cloud.flag(prop::kSynthetic);
    const auto uncoloured_map = cloud.flag("uncoloured");
    const auto confidence_map = cloud.float_map(prop::kConfidence);
    const bool has_colors = cloud.has_colors();
    std::optional<PointCloud::ColorMaps> colors;
    if (has_colors) colors = cloud.colors();
    std::vector<std::int32_t> grid(static_cast<std::size_t>(width) * height, -1);
    std::vector<Eigen::Vector3d> xyz(n);
    std::vector<Eigen::Vector2d> uvc(n);
    std::vector<Rgb> rgb(n);
    std::vector<std::uint8_t> usable(n, 0);  // 1 = on the grid, seen by the colour camera
    for (std::size_t i = 0; i < n; ++i) {
        const PointSet::Index idx(i);
        if (synthetic && (*synthetic)[idx]) continue;
        const std::uint32_t pix = (*pixel_map)[idx];
        if (pix >= grid.size()) continue;
        if (grid[pix] < 0) grid[pix] = static_cast<std::int32_t>(i);
    }
    const Pose& c_from_d = frame.color_from_depth;
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, n, 4096), [&](const tbb::blocked_range<std::size_t>& r) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                const PointSet::Index idx(i);
                const std::uint32_t pix = (*pixel_map)[idx];
                if (pix >= grid.size() || grid[pix] != static_cast<std::int32_t>(i)) continue;
                xyz[i] = sensor_from_view * to_eigen(cloud.points.point(idx));
                const Eigen::Vector3d pc = c_from_d * xyz[i];
                if (!(xyz[i].z() > 0.0) || !(pc.z() > 0.0)) continue;
                uvc[i] = kc.project(pc);
                if (!std::isfinite(uvc[i].x()) || !std::isfinite(uvc[i].y()) ||
                    !kc.contains(uvc[i]))
                    continue;
                if (uncoloured_map && (*uncoloured_map)[idx]) continue;
                rgb[i] =
                    has_colors ? colors->get(idx) : bilinear(frame.color, uvc[i].x(), uvc[i].y());
                usable[i] = 1;
            }
        });
    const double time_prepare_s = watch.seconds();
    if (!report_progress(progress, 0.2)) throw AlgorithmError(name + ": upsample cancelled");

    // Geometry of the colour camera in the depth frame and the colour-pixel steps.
    const Eigen::Matrix3d r_dc = c_from_d.linear().transpose();
    const Eigen::Vector3d origin = -(r_dc * c_from_d.translation());
    const bool distorted = !kc.distortion.is_none();
    const double rho_u = kc.fx / kd.fx, rho_v = kc.fy / kd.fy;
    const double rho = 0.5 * (rho_u + rho_v);
    const double step_u = rho_u / 3.0, step_v = rho_v / 3.0;
    const bool integer_steps = step_u >= 0.75 && step_v >= 0.75;
    const int istep_u = static_cast<int>(std::lround(step_u));
    const int istep_v = static_cast<int>(std::lround(step_v));
    const double tan_theta = std::tan(options.theta_max_deg * M_PI / 180.0);
    const double cos_grazing = std::cos(options.grazing_max_deg * M_PI / 180.0);
    const double cos2_grazing = cos_grazing * cos_grazing;
    const double max_offset2 = options.max_offset_factor * options.max_offset_factor;
    // Undistorted colour ray through pixel (u, v), in the depth frame: ray0 + u ray_du + v ray_dv.
    const Eigen::Vector3d ray_du = r_dc.col(0) / kc.fx, ray_dv = r_dc.col(1) / kc.fy;
    const Eigen::Vector3d ray0 = r_dc.col(2) - kc.cx * ray_du - kc.cy * ray_dv;
    const bool midpoints = options.method == UpsampleMethod::kMidpoints;
    const int k_children = midpoints ? options.neighbors / 2 : options.neighbors;

    // Kernel look-up tables: spatial on the squared colour-pixel distance (1/8 px^2 steps),
    // range on the mean absolute RGB difference (integer levels).
    const double sigma_s = options.sigma_spatial * rho;
    constexpr int kSpatialBins = 4096;
    constexpr double kSpatialStep = 8.0;  // bins per px^2
    std::array<float, kSpatialBins> spatial_lut;
    for (int b = 0; b < kSpatialBins; ++b)
        spatial_lut[b] =
            static_cast<float>(std::exp(-(b / kSpatialStep) / (2.0 * sigma_s * sigma_s)));
    std::array<float, 256> range_lut;
    for (int b = 0; b < 256; ++b)
        range_lut[b] = static_cast<float>(
            std::exp(-(b * b) / (2.0 * options.sigma_color * options.sigma_color)));

    // Children per row (capacity reserved up front: no allocation in the inner loop).
    std::vector<std::vector<Child>> row_children(height);
    std::vector<Counters> row_counts(height);
    std::vector<std::uint32_t> row_points(height, 0);
    for (std::size_t pix = 0; pix < grid.size(); ++pix)
        if (grid[pix] >= 0) ++row_points[pix / width];

    auto at = [&](int col, int row) -> std::int32_t {
        if (col < 0 || row < 0 || col >= width || row >= height) return -1;
        return grid[static_cast<std::size_t>(row) * width + col];
    };

    tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& r) {
        for (int row = r.begin(); row != r.end(); ++row) {
            std::vector<Child>& out = row_children[row];
            out.reserve(static_cast<std::size_t>(row_points[row]) * k_children);
            Counters& count = row_counts[row];
            for (int col = 0; col < width; ++col) {
                const std::int32_t ip = at(col, row);
                if (ip < 0 || !usable[ip]) {
                    if (ip >= 0) ++count.uncoloured;
                    continue;
                }
                const Eigen::Vector3d& xp = xyz[ip];
                const double z = xp.z();
                const double s_d = z / kd.fx;
                const double dz_max = s_d * tan_theta + options.sigma_factor * default_sigma_z(z);
                // Gate: every existing 8-neighbour on the same surface and coloured.
                bool gated = false;
                for (int k = 0; k < 8 && !gated; ++k) {
                    const std::int32_t j = at(col + kDu[k], row + kDv[k]);
                    if (j < 0) continue;
                    gated = !usable[j] || std::abs(xyz[j].z() - z) > dz_max;
                }
                if (gated) {
                    ++count.gated;
                    continue;
                }
                ++count.parents;
                const float parent_conf =
                    confidence_map ? (*confidence_map)[PointSet::Index(ip)] : 1.0f;

                // Normal from the grid: central differences, one-sided at borders.
                auto diff = [&](int du, int dv, Eigen::Vector3d& d) {
                    const std::int32_t a = at(col + du, row + dv), b = at(col - du, row - dv);
                    if (a >= 0 && b >= 0)
                        d = xyz[a] - xyz[b];
                    else if (a >= 0)
                        d = xyz[a] - xp;
                    else if (b >= 0)
                        d = xp - xyz[b];
                    else
                        return false;
                    return true;
                };
                Eigen::Vector3d dx, dy, normal = Eigen::Vector3d::Zero();
                if (diff(1, 0, dx) && diff(0, 1, dy)) normal = dx.cross(dy);
                const double nn = normal.norm();
                if (nn > 0.0) {
                    normal /= nn;
                    if (normal.dot(xp) > 0.0) normal = -normal;
                }

                if (midpoints) {  // Algorithm B: midpoints of grid edges on the same surface.
                    for (int k = 0; k < k_children; ++k) {
                        const std::int32_t j = at(col + kMu[k], row + kMv[k]);
                        if (j < 0 || !usable[j] || std::abs(xyz[j].z() - z) > dz_max) continue;
                        const Eigen::Vector3d m = 0.5 * (xp + xyz[j]);
                        const Eigen::Vector2d q = kc.project(c_from_d * m);
                        if (!kc.contains(q)) {
                            ++count.outside;
                            continue;
                        }
                        const float conf_j =
                            confidence_map ? (*confidence_map)[PointSet::Index(j)] : 1.0f;
                        out.push_back({m, normal, bilinear(frame.color, q.x(), q.y()),
                                       0.8f * std::min(parent_conf, conf_j),
                                       static_cast<std::uint32_t>(ip)});
                    }
                    continue;
                }
                if (!(nn > 0.0)) {
                    ++count.no_normal;
                    continue;
                }

                // Algorithm A: colour pixels around the parent's colour pixel. The 3x3 depth
                // neighbourhood (all usable: the gate passed) is gathered once per parent:
                // colour-image position, colour and the offset of its plane along the normal.
                std::array<Sample, 9> nb;
                int m = 0;
                for (int dv = -1; dv <= 1; ++dv)
                    for (int du = -1; du <= 1; ++du) {
                        const std::int32_t j = at(col + du, row + dv);
                        if (j < 0) continue;
                        nb[m++] = {uvc[j].x(),
                                   uvc[j].y(),
                                   normal.dot(xyz[j] - origin),
                                   {rgb[j].r, rgb[j].g, rgb[j].b},
                                   j};
                    }
                const double h_parent = normal.dot(xp - origin);
                const Eigen::Vector2d& q0 = uvc[ip];
                const double c0u = std::round(q0.x()), c0v = std::round(q0.y());
                for (int k = 0; k < k_children; ++k) {
                    const double qu =
                        integer_steps ? c0u + kDu[k] * istep_u : q0.x() + kDu[k] * step_u;
                    const double qv =
                        integer_steps ? c0v + kDv[k] * istep_v : q0.y() + kDv[k] * step_v;
                    if (qu < 0.0 || qv < 0.0 || qu > kc.width - 1 || qv > kc.height - 1) {
                        ++count.outside;
                        continue;
                    }
                    // Ownership first: the colour pixel belongs to the nearest projection.
                    const double d2p =
                        (q0.x() - qu) * (q0.x() - qu) + (q0.y() - qv) * (q0.y() - qv);
                    double d2s[9];
                    bool owned = true;
                    for (int a = 0; a < m; ++a) {
                        const double eu = nb[a].u - qu, ev = nb[a].v - qv;
                        d2s[a] = eu * eu + ev * ev;
                        if (nb[a].index != ip &&
                            (d2s[a] < d2p || (d2s[a] == d2p && nb[a].index < ip))) {
                            owned = false;
                            break;
                        }
                    }
                    if (!owned) {
                        ++count.owned;
                        continue;
                    }
                    // Ray of the colour pixel, in the depth frame.
                    const Eigen::Vector3d ray =
                        distorted ? Eigen::Vector3d(r_dc * kc.unproject(qu, qv, 1.0))
                                  : Eigen::Vector3d(ray0 + qu * ray_du + qv * ray_dv);
                    const double nr = normal.dot(ray);
                    if (nr * nr < cos2_grazing * ray.squaredNorm()) {
                        ++count.grazing;
                        continue;
                    }
                    const Rgb cq = integer_steps ? bgr_at(frame.color, static_cast<int>(qu),
                                                          static_cast<int>(qv))
                                                 : bilinear(frame.color, qu, qv);
                    // Joint bilateral average of the plane offsets over the 3x3 samples.
                    double wsum = 0.0, wssum = 0.0, hsum = 0.0;
                    for (int a = 0; a < m; ++a) {
                        const int sb =
                            std::min(kSpatialBins - 1, static_cast<int>(d2s[a] * kSpatialStep));
                        const int dc = (std::abs(int(cq.r) - nb[a].rgb[0]) +
                                        std::abs(int(cq.g) - nb[a].rgb[1]) +
                                        std::abs(int(cq.b) - nb[a].rgb[2]) + 1) /
                                       3;
                        const double ws = spatial_lut[sb];
                        const double w = ws * range_lut[std::min(dc, 255)];
                        hsum += w * nb[a].h;
                        wsum += w;
                        wssum += ws;
                    }
                    // Colour unlike every sample: fall back to the parent's plane.
                    const double t = wsum > 1e-12 ? hsum / (wsum * nr) : h_parent / nr;
                    const Eigen::Vector3d y = origin + t * ray;
                    if (!(t > 0.0) || (y - xp).squaredNorm() > max_offset2 * s_d * s_d) {
                        ++count.offset;
                        continue;
                    }
                    const double colour_weight = std::min(1.0, (wsum > 1e-12 ? wsum : 1.0) / wssum);
                    out.push_back({y, normal, cq, static_cast<float>(parent_conf * colour_weight),
                                   static_cast<std::uint32_t>(ip)});
                }
            }
        }
    });
    const double time_children_s = watch.seconds() - time_prepare_s;
    if (!report_progress(progress, 0.8)) throw AlgorithmError(name + ": upsample cancelled");

    // Append in row order (deterministic).
    std::vector<std::size_t> row_offset(height + 1, n);
    for (int row = 0; row < height; ++row)
        row_offset[row + 1] = row_offset[row] + row_children[row].size();
    const std::size_t added = row_offset[height] - n;
    auto new_colors = cloud.add_colors();
    if (!has_colors) {
        for (std::size_t i = 0; i < n; ++i)
            if (usable[i]) new_colors.set(PointSet::Index(i), rgb[i]);
    }
    auto flag = cloud.add_flag(prop::kSynthetic);
    auto confidence = cloud.add_float(prop::kConfidence, 1.0f);
    auto pixels = cloud.add_pixel_map();
    const auto view_ids = cloud.view_map();
    const bool normals = cloud.points.has_normal_map();
    cloud.points.resize(n + added);
    const Pose view_from_sensor = world ? *cloud.view.world_from_sensor : Pose(Pose::Identity());
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
                confidence[idx] = c.confidence;
                pixels[idx] = pixels[parent];
                if (view_ids) (*view_ids)[idx] = (*view_ids)[parent];
            }
        }
    });

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
    Report report;
    report["method"] = midpoints ? "midpoints" : "colour_pixels";
    report["neighbors"] = options.neighbors;
    report["rho"] = rho;
    report["colour_steps"] = integer_steps ? "pixels" : "sub_pixel";
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
