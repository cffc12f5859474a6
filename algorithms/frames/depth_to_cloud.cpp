#include "algorithms/frames/depth_to_cloud.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "algorithms/internal/kd_tree.hpp"
#include "toolkit/error.hpp"

namespace rgbd::frames {

void CloudOptions::check() const {
    RGBD_CHECK(std::isfinite(z_min_m) && z_min_m >= 0.0, "depth window z_min_m must be >= 0");
    RGBD_CHECK(std::isfinite(z_max_m) && z_max_m >= 0.0, "depth window z_max_m must be >= 0");
    RGBD_CHECK(z_max_m == 0.0 || z_max_m > z_min_m, "depth window z_max_m must exceed z_min_m");
    check_range("sigma_factor", sigma_factor, Range::closed(0.0, 100.0));
    check_range("occlusion_margin_m", occlusion_margin_m, Range::closed(0.0, 1.0), "m");
    check_range("splat_scale", splat_scale, Range::closed(0.5, 10.0));
    check_range("max_splat_radius_px", max_splat_radius_px, Range::closed(1, 64));
}

namespace {

enum PixelState : std::uint8_t { kInvalid = 0, kOutsideWindow, kMasked, kValid };

std::string frame_name(const RgbdFrame& frame) {
    std::string name = "frame " + std::to_string(frame.frame_index);
    if (!frame.sensor_id.empty()) name += " of sensor " + frame.sensor_id;
    if (!frame.source.empty()) name += " (" + frame.source + ")";
    return name;
}

/// Throws naming the frame when the `what` ("depth", "colour") image is not of `type`
/// (`type_text`), its intrinsics are invalid or its size is not theirs.
void check_image(const cv::Mat& image, int type, const char* type_text,
                 const PinholeIntrinsics& intrinsics, const std::string& what,
                 const std::string& name) {
    RGBD_CHECK(image.type() == type, name + ": " + what + " image must be " + type_text);
    try {
        intrinsics.check();
    } catch (const InputError& e) {
        throw InputError(name + ": " + what + " intrinsics: " + e.what());
    }
    RGBD_CHECK(image.cols == intrinsics.width && image.rows == intrinsics.height,
               name + ": " + what + " image size differs from the " + what + " intrinsics");
}

void check_frame(const RgbdFrame& frame, bool use_mask, const std::string& name) {
    RGBD_CHECK(!frame.depth.empty(), name + ": depth image is empty");
    check_image(frame.depth, CV_32FC1, "CV_32FC1 metres", frame.depth_intrinsics, "depth", name);
    if (!frame.color.empty()) {
        check_image(frame.color, CV_8UC3, "CV_8UC3 BGR", frame.color_intrinsics, "colour", name);
        RGBD_CHECK(frame.color_from_depth.matrix().allFinite(),
                   name + ": color_from_depth is not finite");
    }
    if (use_mask && !frame.mask.empty()) {
        RGBD_CHECK(frame.mask.type() == CV_8UC1 && frame.mask.size() == frame.depth.size(),
                   name + ": mask must be CV_8UC1 of the depth size");
    }
    if (!frame.confidence.empty()) {
        RGBD_CHECK(
            frame.confidence.type() == CV_32FC1 && frame.confidence.size() == frame.depth.size(),
            name + ": confidence must be CV_32FC1 of the depth size");
    }
    if (frame.has_pose) {
        RGBD_CHECK(frame.world_from_sensor.matrix().allFinite(),
                   name + ": world_from_sensor is not finite");
    }
}

/// Default axial noise model of docs/algorithms.md §4 (noise models), metres.
double default_sigma_z(double z) { return 0.0015 * (z / 1.5) * (z / 1.5); }

/// Atomic minimum on a float slot: the final value is independent of the order of writes.
void atomic_min(float& slot, float value) {
    std::atomic_ref<float> ref(slot);
    float current = ref.load(std::memory_order_relaxed);
    while (value < current &&
           !ref.compare_exchange_weak(current, value, std::memory_order_relaxed)) {
    }
}

/// Per-point state of the colour mapping.
enum ColourState : std::uint8_t { kColoured = 0, kHidden = 1, kOutside = 2 };

/// The depth window [z_min, z_max] in metres: the options' limits, else the sensor's range
/// (0 and +inf when unknown). InputError naming the frame when it is empty.
std::pair<double, double> depth_window(const RgbdFrame& frame, const CloudOptions& options,
                                       const std::string& name) {
    double z_min = options.z_min_m > 0.0 ? options.z_min_m : frame.range_min_m;
    double z_max = options.z_max_m > 0.0 ? options.z_max_m : frame.range_max_m;
    if (!(z_min > 0.0)) z_min = 0.0;
    if (!(z_max > 0.0)) z_max = std::numeric_limits<double>::infinity();
    RGBD_CHECK(z_max > z_min, name + ": depth window is empty (z_max <= z_min)");
    return {z_min, z_max};
}

/// Every depth pixel's PixelState, row-major, and where each row's valid pixels start in the
/// output (row_offset[height] = the number of points).
struct PixelClasses {
    std::vector<std::uint8_t> state;
    std::vector<std::size_t> row_offset;
};

/// Pass 1: classifies every pixel (no return, outside the depth window [z_min, z_max], masked
/// out when `use_mask`, valid) and counts the valid pixels per row.
PixelClasses classify_pixels(const RgbdFrame& frame, double z_min, double z_max, bool use_mask) {
    const int width = frame.depth.cols, height = frame.depth.rows;
    PixelClasses pc;
    pc.state.resize(static_cast<std::size_t>(width) * height);
    std::vector<std::uint32_t> row_valid(height, 0);
    tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& r) {
        for (int row = r.begin(); row != r.end(); ++row) {
            const float* depth = frame.depth.ptr<float>(row);
            const std::uint8_t* mask = use_mask ? frame.mask.ptr<std::uint8_t>(row) : nullptr;
            std::uint32_t count = 0;
            for (int col = 0; col < width; ++col) {
                const double z = depth[col];
                std::uint8_t s = kValid;
                if (!std::isfinite(z) || z <= 0.0)
                    s = kInvalid;
                else if (z < z_min || z > z_max)
                    s = kOutsideWindow;
                else if (mask && mask[col] == 0)
                    s = kMasked;
                pc.state[static_cast<std::size_t>(row) * width + col] = s;
                count += s == kValid;
            }
            row_valid[row] = count;
        }
    });
    pc.row_offset.assign(height + 1, 0);
    for (int row = 0; row < height; ++row)
        pc.row_offset[row + 1] = pc.row_offset[row] + row_valid[row];
    return pc;
}

/// The points of the valid pixels, in row-major pixel order, and their view in the colour camera
/// (colour members empty without a colour image).
struct Points {
    std::vector<Eigen::Vector3d> xyz;  ///< depth-camera frame
    std::vector<std::uint32_t> pixel;  ///< row * width + col
    std::vector<Eigen::Vector2d> uv;   ///< colour-image position
    std::vector<double> zc;            ///< depth in the colour camera
    std::vector<std::uint8_t> cstate;  ///< ColourState
};

/// Pass 2: back-projects the valid pixels with the depth intrinsics and projects them into the
/// colour camera (kOutside when behind it or outside its image).
Points back_project(const RgbdFrame& frame, const PixelClasses& pc) {
    const int width = frame.depth.cols, height = frame.depth.rows;
    const std::size_t n = pc.row_offset[height];
    const bool has_color = !frame.color.empty();
    const PinholeIntrinsics& kd = frame.depth_intrinsics;
    const PinholeIntrinsics& kc = frame.color_intrinsics;
    Points pts;
    pts.xyz.resize(n);
    pts.pixel.resize(n);
    pts.uv.resize(has_color ? n : 0);
    pts.zc.resize(has_color ? n : 0);
    pts.cstate.assign(has_color ? n : 0, kColoured);
    const Pose& c_from_d = frame.color_from_depth;
    tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& r) {
        for (int row = r.begin(); row != r.end(); ++row) {
            const float* depth = frame.depth.ptr<float>(row);
            std::size_t out = pc.row_offset[row];
            for (int col = 0; col < width; ++col) {
                const std::size_t pix = static_cast<std::size_t>(row) * width + col;
                if (pc.state[pix] != kValid) continue;
                const Eigen::Vector3d p = kd.unproject(col, row, depth[col]);
                pts.xyz[out] = p;
                pts.pixel[out] = static_cast<std::uint32_t>(pix);
                if (has_color) {
                    const Eigen::Vector3d q = c_from_d * p;
                    pts.zc[out] = q.z();
                    if (q.z() <= 0.0) {
                        pts.cstate[out] = kOutside;
                    } else {
                        pts.uv[out] = kc.project(q);
                        if (!std::isfinite(pts.uv[out].x()) || !std::isfinite(pts.uv[out].y()) ||
                            !kc.contains(pts.uv[out]))
                            pts.cstate[out] = kOutside;
                    }
                }
                ++out;
            }
        }
    });
    return pts;
}

/// Pass 3: z-buffer in colour space (row-major, +inf where nothing lands), one splat of the
/// depth-pixel footprint (splat_scale, at most max_splat_radius_px) per point the colour
/// camera sees.
std::vector<float> colour_zbuffer(const RgbdFrame& frame, const Points& pts,
                                  const CloudOptions& options) {
    const PinholeIntrinsics& kd = frame.depth_intrinsics;
    const PinholeIntrinsics& kc = frame.color_intrinsics;
    const int cw = kc.width, ch = kc.height;
    std::vector<float> zbuffer(static_cast<std::size_t>(cw) * ch,
                               std::numeric_limits<float>::infinity());
    const double ratio_u = kc.fx / kd.fx * options.splat_scale * 0.5;
    const double ratio_v = kc.fy / kd.fy * options.splat_scale * 0.5;
    const double max_half = options.max_splat_radius_px;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pts.xyz.size(), 1024),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t i = r.begin(); i != r.end(); ++i) {
                              if (pts.cstate[i] != kColoured) continue;
                              const double scale = pts.xyz[i].z() / pts.zc[i];
                              const double hu = std::clamp(ratio_u * scale, 0.5, max_half);
                              const double hv = std::clamp(ratio_v * scale, 0.5, max_half);
                              const Eigen::Vector2d& q = pts.uv[i];
                              const int u0 = std::max(0, int(std::ceil(q.x() - hu)));
                              const int u1 = std::min(cw - 1, int(std::floor(q.x() + hu)));
                              const int v0 = std::max(0, int(std::ceil(q.y() - hv)));
                              const int v1 = std::min(ch - 1, int(std::floor(q.y() + hv)));
                              const float z = static_cast<float>(pts.zc[i]);
                              for (int v = v0; v <= v1; ++v)
                                  for (int u = u0; u <= u1; ++u)
                                      atomic_min(zbuffer[static_cast<std::size_t>(v) * cw + u], z);
                          }
                      });
    return zbuffer;
}

/// The colour of point i (at colour-image position (u, v), depth zc in the colour camera):
/// depth-aware bilinear sample, the taps whose z-buffer shows a different surface (beyond tol;
/// every tap without `zbuffer`) left out, so colour does not bleed across edges; the rounded
/// tap when no tap has weight. Returns false (point hidden) when the rounded tap's z-buffer
/// lies more than tol in front of it.
bool sample_colour(const cv::Mat& color, const std::vector<float>* zbuffer, double u, double v,
                   double zc, double tol, Rgb& rgb) {
    const int cw = color.cols, ch = color.rows;
    auto consistent = [&](int tu, int tv) {
        if (!zbuffer) return true;
        const double b = (*zbuffer)[static_cast<std::size_t>(tv) * cw + tu];
        return std::abs(zc - b) <= tol;
    };
    const int ru = std::clamp(int(std::lround(u)), 0, cw - 1);
    const int rv = std::clamp(int(std::lround(v)), 0, ch - 1);
    if (zbuffer && zc - (*zbuffer)[static_cast<std::size_t>(rv) * cw + ru] > tol) return false;
    const int x0 = int(std::floor(u)), y0 = int(std::floor(v));
    const double ax = u - x0, ay = v - y0;
    double acc[3] = {0, 0, 0};
    double wsum = 0.0;
    for (int dy = 0; dy < 2; ++dy) {
        for (int dx = 0; dx < 2; ++dx) {
            const double w = (dx ? ax : 1.0 - ax) * (dy ? ay : 1.0 - ay);
            if (w <= 0.0) continue;
            const int tu = std::clamp(x0 + dx, 0, cw - 1);
            const int tv = std::clamp(y0 + dy, 0, ch - 1);
            if (!consistent(tu, tv)) continue;
            const cv::Vec3b bgr = color.at<cv::Vec3b>(tv, tu);
            acc[0] += w * bgr[2];
            acc[1] += w * bgr[1];
            acc[2] += w * bgr[0];
            wsum += w;
        }
    }
    if (wsum <= 0.0) {  // only when the rounded tap has zero weight: use it
        const cv::Vec3b bgr = color.at<cv::Vec3b>(rv, ru);
        rgb = {bgr[2], bgr[1], bgr[0]};
        return true;
    }
    auto to8 = [&](double c) {
        return static_cast<std::uint8_t>(std::clamp(c / wsum + 0.5, 0.0, 255.0));
    };
    rgb = {to8(acc[0]), to8(acc[1]), to8(acc[2])};
    return true;
}

/// Pass 4: visibility test and colour sample (sample_colour()) of every point the colour
/// camera sees; a point hidden behind another surface (tolerance sigma_factor sigma_z +
/// occlusion_margin_m) becomes kHidden. No `zbuffer`: no visibility test.
std::vector<Rgb> sample_colours(const RgbdFrame& frame, const std::vector<float>* zbuffer,
                                const CloudOptions& options, Points& pts) {
    const std::size_t n = pts.xyz.size();
    std::vector<Rgb> rgb(n);
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, n, 1024), [&](const tbb::blocked_range<std::size_t>& r) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                if (pts.cstate[i] != kColoured) continue;
                const double tol = options.sigma_factor * default_sigma_z(pts.xyz[i].z()) +
                                   options.occlusion_margin_m;
                if (!sample_colour(frame.color, zbuffer, pts.uv[i].x(), pts.uv[i].y(), pts.zc[i],
                                   tol, rgb[i]))
                    pts.cstate[i] = kHidden;
            }
        });
    return rgb;
}

/// Pass 5, first half: the points the colour camera did not see (hidden) or that fall outside
/// its image (outside) are counted and given `fallback`; colour_uncoloured(PointCloud&) colours
/// them from their nearest coloured point once the cloud is made (CloudOptions::colour_hidden),
/// or later. Returns the numbers of hidden and outside points.
std::pair<std::size_t, std::size_t> fall_back_uncoloured(const Points& pts, const Rgb& fallback,
                                                         std::vector<Rgb>& rgb) {
    std::size_t hidden = 0, outside = 0;
    for (std::size_t i = 0; i < pts.xyz.size(); ++i) {
        hidden += pts.cstate[i] == kHidden;
        outside += pts.cstate[i] == kOutside;
        if (pts.cstate[i] != kColoured) rgb[i] = fallback;
    }
    return {hidden, outside};
}

/// The output cloud, row-major pixel order, in the sensor frame with the frame's metadata:
/// pixel, confidence (the frame's, clamped to [0, 1], 0 where not finite; else 1) and, with a
/// colour image, colour and the uncoloured flag.
PointCloud organised_cloud(const RgbdFrame& frame, const Points& pts, const std::vector<Rgb>& rgb) {
    const int width = frame.depth.cols;
    const std::size_t n = pts.xyz.size();
    const bool has_color = !frame.color.empty();
    PointCloud cloud;
    cloud.view.frame = ViewFrame::kSensor;
    cloud.view.sensor = frame.sensor_id;
    cloud.view.time_ns = frame.timestamp_ns;
    cloud.view.intrinsics = frame.depth_intrinsics;
    if (frame.has_pose) cloud.view.world_from_sensor = frame.world_from_sensor;
    cloud.view.grid_width = width;
    cloud.view.grid_height = frame.depth.rows;
    cloud.view.source = frame.source;
    cloud.points.resize(n);
    auto pixel_map = cloud.add_pixel_map();
    auto confidence = cloud.add_float(prop::kConfidence, 1.0f);
    std::optional<PointCloud::ColorMaps> colors;
    std::optional<PointCloud::Uint8Map> uncoloured;
    if (has_color) {
        colors = cloud.add_colors();
        uncoloured = cloud.add_flag(kUncoloured);
    }
    const bool has_confidence = !frame.confidence.empty();
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, n, 4096), [&](const tbb::blocked_range<std::size_t>& r) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                const PointSet::Index idx(i);
                cloud.points.point(idx) = to_point(pts.xyz[i]);
                pixel_map[idx] = pts.pixel[i];
                if (has_confidence) {
                    const float c = frame.confidence.at<float>(int(pts.pixel[i] / width),
                                                               int(pts.pixel[i] % width));
                    confidence[idx] = std::isfinite(c) ? std::clamp(c, 0.0f, 1.0f) : 0.0f;
                }
                if (has_color) {
                    colors->set(idx, rgb[i]);
                    (*uncoloured)[idx] = pts.cstate[i] != kColoured ? 1 : 0;
                }
            }
        });
    return cloud;
}

}  // namespace

PointCloud depth_to_cloud(const RgbdFrame& frame, const CloudOptions& options, Report* report) {
    Stopwatch watch;
    options.check();
    const std::string name = frame_name(frame);
    check_frame(frame, options.use_mask, name);

    const auto [z_min, z_max] = depth_window(frame, options, name);
    const bool use_mask = options.use_mask && !frame.mask.empty();
    const PixelClasses classes = classify_pixels(frame, z_min, z_max, use_mask);
    Points pts = back_project(frame, classes);
    const std::size_t n = pts.xyz.size();

    // Colour: visibility in the colour camera, colour sample, the rest from their neighbours.
    const bool has_color = !frame.color.empty();
    std::vector<Rgb> rgb;
    std::size_t hidden = 0, outside = 0;
    if (has_color) {
        std::vector<float> zbuffer;
        if (options.visibility_test) zbuffer = colour_zbuffer(frame, pts, options);
        rgb = sample_colours(frame, options.visibility_test ? &zbuffer : nullptr, options, pts);
        std::tie(hidden, outside) = fall_back_uncoloured(pts, options.fallback_color, rgb);
    }
    PointCloud cloud = organised_cloud(frame, pts, rgb);
    // Pass 5, second half: from the nearest coloured point (3D distance, so a background point
    // never takes the colour of the foreground across an edge).
    if (has_color && options.colour_hidden) colour_uncoloured(cloud, options.fallback_color);

    if (report) {
        std::size_t invalid = 0, window = 0, masked = 0;
        for (std::uint8_t s : classes.state) {
            invalid += s == kInvalid;
            window += s == kOutsideWindow;
            masked += s == kMasked;
        }
        Report& rep = *report;
        rep["z_min_m"] = z_min;
        rep["z_max_m"] = std::isfinite(z_max) ? nlohmann::json(z_max) : nlohmann::json(nullptr);
        rep["mask_used"] = use_mask;
        rep["pixels"] = classes.state.size();
        rep["points"] = n;
        rep["invalid_depth"] = invalid;
        rep["removed_depth_window"] = window;
        rep["removed_mask"] = masked;
        rep["has_color"] = has_color;
        rep["uncoloured_hidden"] = hidden;
        rep["uncoloured_outside"] = outside;
        rep["time_s"] = watch.seconds();
    }
    return cloud;
}

std::size_t colour_uncoloured(PointCloud& cloud, const Rgb& fallback) {
    const auto flag = cloud.flag(kUncoloured);
    if (!flag || !cloud.has_colors()) return 0;
    auto colors = cloud.colors();
    std::vector<Eigen::Vector3d> coloured_xyz;
    std::vector<PointSet::Index> coloured_id, uncoloured_id;
    for (auto idx : cloud.points) {
        if ((*flag)[idx]) {
            uncoloured_id.push_back(idx);
        } else {
            coloured_xyz.push_back(to_eigen(cloud.points.point(idx)));
            coloured_id.push_back(idx);
        }
    }
    if (uncoloured_id.empty()) return 0;
    const internal::KdTree tree(coloured_xyz);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, uncoloured_id.size(), 1024),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t a = r.begin(); a != r.end(); ++a) {
                              const PointSet::Index idx = uncoloured_id[a];
                              std::uint32_t nearest = 0;
                              double sq = 0.0;
                              colors.set(
                                  idx, tree.nearest(to_eigen(cloud.points.point(idx)), nearest, sq)
                                           ? colors.get(coloured_id[nearest])
                                           : fallback);
                          }
                      });
    return uncoloured_id.size();
}

}  // namespace rgbd::frames
