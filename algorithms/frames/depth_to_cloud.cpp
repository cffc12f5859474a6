#include "algorithms/frames/depth_to_cloud.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
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

}  // namespace

PointCloud depth_to_cloud(const RgbdFrame& frame, const CloudOptions& options, Report* report) {
    Stopwatch watch;
    options.check();
    const std::string name = frame_name(frame);
    check_frame(frame, options.use_mask, name);

    const int width = frame.depth.cols;
    const int height = frame.depth.rows;
    const PinholeIntrinsics& kd = frame.depth_intrinsics;

    // Resolve the depth window.
    double z_min = options.z_min_m > 0.0 ? options.z_min_m : frame.range_min_m;
    double z_max = options.z_max_m > 0.0 ? options.z_max_m : frame.range_max_m;
    if (!(z_min > 0.0)) z_min = 0.0;
    if (!(z_max > 0.0)) z_max = std::numeric_limits<double>::infinity();
    RGBD_CHECK(z_max > z_min, name + ": depth window is empty (z_max <= z_min)");
    const bool use_mask = options.use_mask && !frame.mask.empty();

    // Pass 1: classify every pixel, count valid pixels per row.
    std::vector<std::uint8_t> state(static_cast<std::size_t>(width) * height);
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
                state[static_cast<std::size_t>(row) * width + col] = s;
                count += s == kValid;
            }
            row_valid[row] = count;
        }
    });
    std::vector<std::size_t> row_offset(height + 1, 0);
    for (int row = 0; row < height; ++row) row_offset[row + 1] = row_offset[row] + row_valid[row];
    const std::size_t n = row_offset[height];

    // Pass 2: back-project; project into the colour camera.
    const bool has_color = !frame.color.empty();
    const PinholeIntrinsics& kc = frame.color_intrinsics;
    std::vector<Eigen::Vector3d> xyz(n);
    std::vector<std::uint32_t> pixel(n);
    std::vector<Eigen::Vector2d> uv(has_color ? n : 0);
    std::vector<double> zc(has_color ? n : 0);
    std::vector<std::uint8_t> cstate(has_color ? n : 0, kColoured);
    const Pose& c_from_d = frame.color_from_depth;
    tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& r) {
        for (int row = r.begin(); row != r.end(); ++row) {
            const float* depth = frame.depth.ptr<float>(row);
            std::size_t out = row_offset[row];
            for (int col = 0; col < width; ++col) {
                const std::size_t pix = static_cast<std::size_t>(row) * width + col;
                if (state[pix] != kValid) continue;
                const Eigen::Vector3d p = kd.unproject(col, row, depth[col]);
                xyz[out] = p;
                pixel[out] = static_cast<std::uint32_t>(pix);
                if (has_color) {
                    const Eigen::Vector3d pc = c_from_d * p;
                    zc[out] = pc.z();
                    if (pc.z() <= 0.0) {
                        cstate[out] = kOutside;
                    } else {
                        uv[out] = kc.project(pc);
                        if (!std::isfinite(uv[out].x()) || !std::isfinite(uv[out].y()) ||
                            !kc.contains(uv[out]))
                            cstate[out] = kOutside;
                    }
                }
                ++out;
            }
        }
    });

    // Pass 3: z-buffer in colour space, one splat of the depth-pixel footprint per point.
    const int cw = has_color ? kc.width : 0;
    const int ch = has_color ? kc.height : 0;
    std::vector<float> zbuffer;
    const bool zbuffered = has_color && options.visibility_test;
    if (zbuffered) {
        zbuffer.assign(static_cast<std::size_t>(cw) * ch, std::numeric_limits<float>::infinity());
        const double ratio_u = kc.fx / kd.fx * options.splat_scale * 0.5;
        const double ratio_v = kc.fy / kd.fy * options.splat_scale * 0.5;
        const double max_half = options.max_splat_radius_px;
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1024),
                          [&](const tbb::blocked_range<std::size_t>& r) {
                              for (std::size_t i = r.begin(); i != r.end(); ++i) {
                                  if (cstate[i] != kColoured) continue;
                                  const double scale = xyz[i].z() / zc[i];
                                  const double hu = std::clamp(ratio_u * scale, 0.5, max_half);
                                  const double hv = std::clamp(ratio_v * scale, 0.5, max_half);
                                  const int u0 = std::max(0, int(std::ceil(uv[i].x() - hu)));
                                  const int u1 = std::min(cw - 1, int(std::floor(uv[i].x() + hu)));
                                  const int v0 = std::max(0, int(std::ceil(uv[i].y() - hv)));
                                  const int v1 = std::min(ch - 1, int(std::floor(uv[i].y() + hv)));
                                  const float z = static_cast<float>(zc[i]);
                                  for (int v = v0; v <= v1; ++v)
                                      for (int u = u0; u <= u1; ++u)
                                          atomic_min(zbuffer[static_cast<std::size_t>(v) * cw + u],
                                                     z);
                              }
                          });
    }

    // Pass 4: visibility test and depth-aware bilinear colour sample (taps that show a
    // different surface than the point are left out, so colour does not bleed across edges).
    std::vector<Rgb> rgb(has_color ? n : 0);
    if (has_color) {
        tbb::parallel_for(
            tbb::blocked_range<std::size_t>(0, n, 1024),
            [&](const tbb::blocked_range<std::size_t>& r) {
                for (std::size_t i = r.begin(); i != r.end(); ++i) {
                    if (cstate[i] != kColoured) continue;
                    const double u = uv[i].x(), v = uv[i].y();
                    const double tol = options.sigma_factor * default_sigma_z(xyz[i].z()) +
                                       options.occlusion_margin_m;
                    auto consistent = [&](int tu, int tv) {
                        if (!zbuffered) return true;
                        const double b = zbuffer[static_cast<std::size_t>(tv) * cw + tu];
                        return std::abs(zc[i] - b) <= tol;
                    };
                    const int ru = std::clamp(int(std::lround(u)), 0, cw - 1);
                    const int rv = std::clamp(int(std::lround(v)), 0, ch - 1);
                    if (zbuffered &&
                        zc[i] - zbuffer[static_cast<std::size_t>(rv) * cw + ru] > tol) {
                        cstate[i] = kHidden;
                        continue;
                    }
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
                            const cv::Vec3b bgr = frame.color.at<cv::Vec3b>(tv, tu);
                            acc[0] += w * bgr[2];
                            acc[1] += w * bgr[1];
                            acc[2] += w * bgr[0];
                            wsum += w;
                        }
                    }
                    if (wsum <= 0.0) {  // only when the rounded tap has zero weight: use it
                        const cv::Vec3b bgr = frame.color.at<cv::Vec3b>(rv, ru);
                        rgb[i] = {bgr[2], bgr[1], bgr[0]};
                        continue;
                    }
                    auto to8 = [&](double c) {
                        return static_cast<std::uint8_t>(std::clamp(c / wsum + 0.5, 0.0, 255.0));
                    };
                    rgb[i] = {to8(acc[0]), to8(acc[1]), to8(acc[2])};
                }
            });
    }

    // Pass 5: uncoloured points take the colour of the nearest coloured point (3D distance,
    // so a background point never takes the colour of the foreground across an edge).
    std::size_t hidden = 0, outside = 0;
    if (has_color) {
        std::vector<Eigen::Vector3d> coloured_xyz;
        std::vector<std::uint32_t> coloured_id;
        for (std::size_t i = 0; i < n; ++i) {
            hidden += cstate[i] == kHidden;
            outside += cstate[i] == kOutside;
            if (cstate[i] == kColoured) {
                coloured_xyz.push_back(xyz[i]);
                coloured_id.push_back(static_cast<std::uint32_t>(i));
            }
        }
        if (hidden + outside > 0) {
            const internal::KdTree tree(coloured_xyz);
            tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1024),
                              [&](const tbb::blocked_range<std::size_t>& r) {
                                  for (std::size_t i = r.begin(); i != r.end(); ++i) {
                                      if (cstate[i] == kColoured) continue;
                                      std::uint32_t nearest = 0;
                                      double sq = 0.0;
                                      rgb[i] = tree.nearest(xyz[i], nearest, sq)
                                                   ? rgb[coloured_id[nearest]]
                                                   : options.fallback_color;
                                  }
                              });
        }
    }

    // Output cloud, row-major pixel order.
    PointCloud cloud;
    cloud.view.frame = ViewFrame::kSensor;
    cloud.view.sensor = frame.sensor_id;
    cloud.view.time_ns = frame.timestamp_ns;
    cloud.view.intrinsics = kd;
    if (frame.has_pose) cloud.view.world_from_sensor = frame.world_from_sensor;
    cloud.view.grid_width = width;
    cloud.view.grid_height = height;
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
                cloud.points.point(idx) = to_point(xyz[i]);
                pixel_map[idx] = pixel[i];
                if (has_confidence) {
                    const float c =
                        frame.confidence.at<float>(int(pixel[i] / width), int(pixel[i] % width));
                    confidence[idx] = std::isfinite(c) ? std::clamp(c, 0.0f, 1.0f) : 0.0f;
                }
                if (has_color) {
                    colors->set(idx, rgb[i]);
                    (*uncoloured)[idx] = cstate[i] != kColoured ? 1 : 0;
                }
            }
        });

    if (report) {
        std::size_t invalid = 0, window = 0, masked = 0;
        for (std::uint8_t s : state) {
            invalid += s == kInvalid;
            window += s == kOutsideWindow;
            masked += s == kMasked;
        }
        Report& rep = *report;
        rep["z_min_m"] = z_min;
        rep["z_max_m"] = std::isfinite(z_max) ? nlohmann::json(z_max) : nlohmann::json(nullptr);
        rep["mask_used"] = use_mask;
        rep["pixels"] = state.size();
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

}  // namespace rgbd::frames
