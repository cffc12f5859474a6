#include "validation/synth/noise.hpp"

#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "toolkit/error.hpp"
#include "validation/synth/random.hpp"

namespace rgbd::synth {
namespace {

constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();

// Random streams, one per kind of draw.
enum Stream : std::uint64_t {
    kJitterU = 1,
    kJitterV,
    kFlyingPick,
    kFlyingWeight,
    kGrazing,
    kDropout,
    kAxial,
    kOutlierPick,
    kOutlierDepth,
    kColor,
};

/// Incidence angle of the pixel ray on the surface with camera-frame normal n.
double incidence_rad(const PinholeIntrinsics& k, int row, int col, const cv::Vec3f& n) {
    const Eigen::Vector3d ray =
        Eigen::Vector3d((col - k.cx) / k.fx, (row - k.cy) / k.fy, 1.0).normalized();
    const double c = std::abs(ray.x() * n[0] + ray.y() * n[1] + ray.z() * n[2]);
    return std::acos(std::clamp(c, 0.0, 1.0));
}

}  // namespace

std::string to_string(DepthNoiseModel model) {
    return model == DepthNoiseModel::kSr300 ? "sr300" : "kinect_v2";
}

double sigma_z_m(DepthNoiseModel model, double z, double theta) {
    const double th = std::clamp(theta, 0.0, 89.0 * std::numbers::pi / 180.0);
    const double grazing = 0.1 * std::pow(z, 1.5) * th * th /
                           ((std::numbers::pi / 2 - th) * (std::numbers::pi / 2 - th));
    const double base_mm =
        model == DepthNoiseModel::kSr300 ? 0.5 + 2.0 * z * z : 1.5 - 0.5 * z + 0.3 * z * z;
    return 1e-3 * (base_mm + grazing);
}

NoiseOptions NoiseOptions::none() {
    NoiseOptions o;
    o.axial = o.lateral = o.flying = o.grazing = o.quantize = false;
    o.dropout_rate = o.outlier_rate = o.color_sigma = 0.0;
    return o;
}

void NoiseOptions::check() const {
    check_range("lateral jitter", lateral_sigma_px, Range::closed(0, 10), "px");
    check_range("flying fraction", flying_fraction, Range::closed(0, 1));
    RGBD_CHECK(std::isfinite(discontinuity_m) && discontinuity_m > 0,
               "discontinuity threshold must be > 0");
    RGBD_CHECK(
        grazing_start_deg >= 0 && grazing_end_deg <= 90 && grazing_start_deg < grazing_end_deg,
        "grazing angles must satisfy 0 <= start < end <= 90");
    check_range("dropout rate", dropout_rate, Range::closed(0, 1));
    check_range("outlier rate", outlier_rate, Range::closed(0, 1));
    check_range("colour noise", color_sigma, Range::closed(0, 100), "grey levels");
}

nlohmann::json NoiseOptions::to_json() const {
    return {{"axial", axial},
            {"lateral", lateral},
            {"lateral_sigma_px", lateral_sigma_px},
            {"flying", flying},
            {"flying_fraction", flying_fraction},
            {"discontinuity_m", discontinuity_m},
            {"void_background", void_background},
            {"grazing", grazing},
            {"grazing_start_deg", grazing_start_deg},
            {"grazing_end_deg", grazing_end_deg},
            {"dropout_rate", dropout_rate},
            {"outlier_rate", outlier_rate},
            {"quantize", quantize},
            {"color_sigma", color_sigma},
            {"color_jpeg", true},
            {"sigma_z_mm",
             {{"kinect_v2", "1.5 - 0.5 z + 0.3 z^2 + 0.1 z^1.5 theta^2 / (pi/2 - theta)^2"},
              {"sr300", "0.5 + 2 z^2 + 0.1 z^1.5 theta^2 / (pi/2 - theta)^2"}}}};
}

NoisyDepth apply_depth_noise(const DepthRender& clean, const PinholeIntrinsics& k,
                             const DepthSensorTraits& sensor, const NoiseOptions& o,
                             std::uint64_t seed) {
    o.check();
    RGBD_CHECK(clean.depth.type() == CV_64FC1 && clean.normal.type() == CV_32FC3 &&
                   clean.depth.size() == clean.normal.size(),
               "apply_depth_noise needs a DepthRender");
    RGBD_CHECK(sensor.range_min_m >= 0 && sensor.range_max_m > sensor.range_min_m,
               "sensor range must satisfy 0 <= min < max");
    RGBD_CHECK(sensor.quantum_m > 0, "depth quantum must be > 0");
    const int w = clean.depth.cols, h = clean.depth.rows;
    RGBD_CHECK(w == k.width && h == k.height, "depth render does not match the intrinsics");
    const CounterRandom rng(seed);
    const auto valid = [](double z) { return std::isfinite(z); };
    const auto idx = [w](int r, int c) { return static_cast<std::uint64_t>(r) * w + c; };
    const double deg = std::numbers::pi / 180.0;

    // In-range clean depth (out-of-range surfaces give no return).
    cv::Mat z0(h, w, CV_64FC1);
    tbb::parallel_for(0, h, [&](int r) {
        for (int c = 0; c < w; ++c) {
            const double z = clean.depth.at<double>(r, c);
            z0.at<double>(r, c) = valid(z) && z >= sensor.range_min_m && z <= sensor.range_max_m
                                      ? z
                                      : std::numeric_limits<double>::quiet_NaN();
        }
    });
    const auto is_edge = [&](const cv::Mat& d, int r, int c) {
        const double z = d.at<double>(r, c);
        for (int dr = -1; dr <= 1; ++dr)
            for (int dc = -1; dc <= 1; ++dc) {
                const int rr = r + dr, cc = c + dc;
                if ((dr == 0 && dc == 0) || rr < 0 || cc < 0 || rr >= h || cc >= w) continue;
                const double q = d.at<double>(rr, cc);
                if (valid(z) != valid(q)) return true;
                if (valid(z) && std::abs(z - q) > o.discontinuity_m) return true;
            }
        return false;
    };

    // 1. Lateral jitter in the edge band: take depth and normal from a displaced pixel.
    cv::Mat z1 = z0.clone();
    cv::Mat n1 = clean.normal.clone();
    if (o.lateral && o.lateral_sigma_px > 0) {
        tbb::parallel_for(0, h, [&](int r) {
            for (int c = 0; c < w; ++c) {
                if (!is_edge(z0, r, c)) continue;
                const int rr = std::clamp(
                    static_cast<int>(
                        std::lround(r + o.lateral_sigma_px * rng.normal(kJitterV, idx(r, c)))),
                    0, h - 1);
                const int cc = std::clamp(
                    static_cast<int>(
                        std::lround(c + o.lateral_sigma_px * rng.normal(kJitterU, idx(r, c)))),
                    0, w - 1);
                z1.at<double>(r, c) = z0.at<double>(rr, cc);
                n1.at<cv::Vec3f>(r, c) = clean.normal.at<cv::Vec3f>(rr, cc);
            }
        });
    }

    // Expected outlier count relative to the surface pixels.
    const std::size_t surface_count = static_cast<std::size_t>(cv::countNonZero(z1 == z1));
    const double outlier_p =
        std::min(1.0, o.outlier_rate * static_cast<double>(surface_count) / (double(w) * h));

    NoisyDepth out;
    out.depth.create(h, w, CV_32FC1);
    out.labels.create(h, w, CV_8UC1);
    tbb::parallel_for(0, h, [&](int r) {
        for (int c = 0; c < w; ++c) {
            const std::uint64_t i = idx(r, c);
            double z = z1.at<double>(r, c);
            auto label = valid(z) ? PixelLabel::kSurface : PixelLabel::kNoReturn;

            // 2. Flying pixels in the 2-px discontinuity band (both sides of the edge).
            if (o.flying && o.flying_fraction > 0 && is_edge(z1, r, c) &&
                rng.uniform(kFlyingPick, i) < o.flying_fraction) {
                double fg = std::numeric_limits<double>::infinity(), bg = -fg;
                bool has_void = false;
                for (int dr = -1; dr <= 1; ++dr)
                    for (int dc = -1; dc <= 1; ++dc) {
                        const int rr = std::clamp(r + dr, 0, h - 1);
                        const int cc = std::clamp(c + dc, 0, w - 1);
                        const double q = z1.at<double>(rr, cc);
                        if (!valid(q)) {
                            has_void = true;
                            continue;
                        }
                        fg = std::min(fg, q);
                        bg = std::max(bg, q);
                    }
                if (has_void && o.void_background) bg = std::max(bg, sensor.range_max_m);
                if (std::isfinite(fg) && bg - fg > o.discontinuity_m) {
                    z = fg + rng.uniform(kFlyingWeight, i) * (bg - fg);
                    label = PixelLabel::kFlying;
                }
            }
            if (label == PixelLabel::kSurface) {
                const double theta = incidence_rad(k, r, c, n1.at<cv::Vec3f>(r, c));
                // 3. Grazing dropouts, probability ramping from 0 to 1.
                if (o.grazing) {
                    const double p = std::clamp((theta / deg - o.grazing_start_deg) /
                                                    (o.grazing_end_deg - o.grazing_start_deg),
                                                0.0, 1.0);
                    if (p > 0 && rng.uniform(kGrazing, i) < p) label = PixelLabel::kDropout;
                }
                // 4. Random dropouts.
                if (label == PixelLabel::kSurface && o.dropout_rate > 0 &&
                    rng.uniform(kDropout, i) < o.dropout_rate)
                    label = PixelLabel::kDropout;
                // 5. Axial noise.
                if (label == PixelLabel::kSurface && o.axial)
                    z += sigma_z_m(sensor.model, z, theta) * rng.normal(kAxial, i);
            }
            // 6. Random outliers anywhere in the frustum within the range.
            if (outlier_p > 0 && rng.uniform(kOutlierPick, i) < outlier_p) {
                z = sensor.range_min_m +
                    rng.uniform(kOutlierDepth, i) * (sensor.range_max_m - sensor.range_min_m);
                label = PixelLabel::kOutlier;
            }
            if (label == PixelLabel::kDropout || label == PixelLabel::kNoReturn) {
                out.depth.at<float>(r, c) = kNaNf;
            } else {
                // 7. Quantisation, then the range limits.
                if (o.quantize) z = std::round(z / sensor.quantum_m) * sensor.quantum_m;
                if (z < sensor.range_min_m || z > sensor.range_max_m) {
                    out.depth.at<float>(r, c) = kNaNf;
                    label = PixelLabel::kNoReturn;
                } else {
                    out.depth.at<float>(r, c) = static_cast<float>(z);
                }
            }
            out.labels.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(label);
        }
    });
    return out;
}

namespace {

/// Standard-normal quantiles at (i + 0.5) / 65536: one 16-bit slice of a random word gives a
/// Gaussian draw (four draws per 64-bit hash; the 1/65536 quantisation is far below one grey
/// level at any sensible sigma).
const std::vector<float>& normal_table() {
    static const std::vector<float> table = [] {
        std::vector<float> t(65536);
        for (int i = 0; i < 65536; ++i) {
            const double target = 2.0 * (i + 0.5) / 65536.0 - 1.0;  // erf(x / sqrt 2)
            double lo = -8.0, hi = 8.0;
            for (int it = 0; it < 60; ++it) {
                const double mid = 0.5 * (lo + hi);
                (std::erf(mid / std::numbers::sqrt2) < target ? lo : hi) = mid;
            }
            t[i] = static_cast<float>(0.5 * (lo + hi));
        }
        return t;
    }();
    return table;
}

}  // namespace

void apply_color_noise(cv::Mat& bgr, double sigma, std::uint64_t seed) {
    RGBD_CHECK(bgr.type() == CV_8UC3, "colour noise needs a CV_8UC3 image");
    RGBD_CHECK(std::isfinite(sigma) && sigma >= 0, "colour noise sigma must be >= 0");
    if (sigma == 0) return;
    const CounterRandom rng(seed);
    const std::vector<float>& table = normal_table();
    const int w = bgr.cols;
    tbb::parallel_for(0, bgr.rows, [&](int r) {
        auto* p = bgr.ptr<cv::Vec3b>(r);
        for (int c = 0; c < w; ++c) {
            const std::uint64_t bits = rng.bits(kColor, static_cast<std::uint64_t>(r) * w + c);
            for (int ch = 0; ch < 3; ++ch) {
                const double v = p[c][ch] + sigma * table[(bits >> (16 * ch)) & 0xffff];
                p[c][ch] = static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
            }
        }
    });
}

}  // namespace rgbd::synth
