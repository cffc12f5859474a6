// Statistics of the synthetic sensor noise: axial std, label rates, grazing dropouts,
// determinism for a seed and any thread count.
#include "validation/synth/noise.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstring>
#include <numbers>

#include "synth_test_shapes.hpp"
#include "toolkit/error.hpp"
#include "validation/synth/synthesize.hpp"

namespace rgbd::synth {
namespace {

int count_label(const cv::Mat& labels, PixelLabel l) {
    return cv::countNonZero(labels == static_cast<int>(l));
}

TEST(Noise, KinectSigmaAtOnePointFiveMetres) {
    EXPECT_NEAR(sigma_z_m(DepthNoiseModel::kKinectV2, 1.5, 0.0), 1.425e-3, 1e-9);
    EXPECT_GT(sigma_z_m(DepthNoiseModel::kKinectV2, 1.5, 1.3),
              3 * sigma_z_m(DepthNoiseModel::kKinectV2, 1.5, 0.0));
    EXPECT_NEAR(sigma_z_m(DepthNoiseModel::kSr300, 0.55, 0.0), 1.105e-3, 1e-9);
}

TEST(Noise, AxialStdMatchesSigmaHeadOn) {
    const io::SensorSpec spec = kinect_v2_spec("k");
    Mesh mesh;
    testing::add_quad(mesh, Eigen::Vector3d(0, 0, 1.5), Eigen::Vector3d::UnitX(),
                      Eigen::Vector3d::UnitY(), 2.0);
    const DepthRender clean = render_depth(RenderScene(mesh), spec.depth, Pose::Identity());
    NoiseOptions o = NoiseOptions::none();
    o.axial = true;
    o.quantize = true;  // 1 mm steps add 0.29 mm rms in quadrature
    const NoisyDepth noisy = apply_depth_noise(clean, spec.depth, traits_of(spec), o, 42);
    double sum = 0, sum2 = 0;
    long n = 0;
    for (int r = 212 - 60; r <= 212 + 60; ++r)  // within ~13 deg of the axis
        for (int c = 256 - 60; c <= 256 + 60; ++c) {
            const double e = noisy.depth.at<float>(r, c) - clean.depth.at<double>(r, c);
            sum += e;
            sum2 += e * e;
            ++n;
        }
    const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
    const double sigma = sigma_z_m(DepthNoiseModel::kKinectV2, 1.5, 0.0);
    EXPECT_NEAR(sd, sigma, 0.2 * sigma);
    EXPECT_NEAR(mean, 0.0, 1e-4);
    EXPECT_EQ(count_label(noisy.labels, PixelLabel::kSurface), 512 * 424);
}

TEST(Noise, LabelCountsFollowTheConfiguredRates) {
    const io::SensorSpec spec = kinect_v2_spec("k");
    const Mesh mesh = testing::ball_before_wall(Eigen::Vector3d(0.2, 0, 2.0), 0.6,
                                                Eigen::Vector3d(0, 0, 1.2), 0.15, 4);
    const DepthRender clean = render_depth(RenderScene(mesh), spec.depth, Pose::Identity());
    NoiseOptions o;  // defaults, without jitter and grazing so that the band is known
    o.lateral = false;
    o.grazing = false;
    const NoisyDepth noisy = apply_depth_noise(clean, spec.depth, traits_of(spec), o, 7);

    const int w = clean.depth.cols, h = clean.depth.rows;
    long band = 0, surface_clean = 0;
    for (int r = 0; r < h; ++r)
        for (int c = 0; c < w; ++c) {
            const double z = clean.depth.at<double>(r, c);
            if (std::isfinite(z)) ++surface_clean;
            bool edge = false;
            for (int dr = -1; dr <= 1; ++dr)
                for (int dc = -1; dc <= 1; ++dc) {
                    const int rr = r + dr, cc = c + dc;
                    if (rr < 0 || cc < 0 || rr >= h || cc >= w) continue;
                    const double q = clean.depth.at<double>(rr, cc);
                    if (std::isfinite(z) != std::isfinite(q) ||
                        (std::isfinite(z) && std::abs(z - q) > o.discontinuity_m))
                        edge = true;
                }
            band += edge;
        }
    ASSERT_GT(band, 2000);
    const int flying = count_label(noisy.labels, PixelLabel::kFlying);
    const int outliers = count_label(noisy.labels, PixelLabel::kOutlier);
    const int dropouts = count_label(noisy.labels, PixelLabel::kDropout);
    const int surface = count_label(noisy.labels, PixelLabel::kSurface);
    EXPECT_NEAR(flying, 0.5 * band, 0.1 * 0.5 * band);
    EXPECT_NEAR(outliers, 0.005 * surface_clean, 0.25 * 0.005 * surface_clean);
    EXPECT_NEAR(dropouts, 0.005 * surface_clean, 0.25 * 0.005 * surface_clean);
    EXPECT_GT(surface, 0.95 * (surface_clean - band));
    // Outliers lie inside the range; dropouts are invalid; flying pixels lie between layers.
    for (int r = 0; r < h; ++r)
        for (int c = 0; c < w; ++c) {
            const auto l = static_cast<PixelLabel>(noisy.labels.at<std::uint8_t>(r, c));
            const float z = noisy.depth.at<float>(r, c);
            if (l == PixelLabel::kDropout || l == PixelLabel::kNoReturn) {
                EXPECT_TRUE(std::isnan(z));
            } else {
                EXPECT_GE(z, 0.5f);
                EXPECT_LE(z, 4.5f);
            }
        }
}

TEST(Noise, GrazingDropoutRampsBetweenSeventyAndEightyFiveDegrees) {
    const io::SensorSpec spec = kinect_v2_spec("k");
    const auto fraction_at = [&](double angle_deg) {
        const double a = angle_deg * std::numbers::pi / 180.0;
        Mesh mesh;
        testing::add_quad(mesh, Eigen::Vector3d(0, 0, 1.5),
                          Eigen::Vector3d(std::cos(a), 0, std::sin(a)), Eigen::Vector3d::UnitY(),
                          1.0);  // stays in front of the near plane
        const DepthRender clean = render_depth(RenderScene(mesh), spec.depth, Pose::Identity());
        NoiseOptions o = NoiseOptions::none();
        o.grazing = true;
        const NoisyDepth noisy = apply_depth_noise(clean, spec.depth, traits_of(spec), o, 3);
        const cv::Mat patch = noisy.labels(cv::Rect(256 - 3, 212 - 40, 7, 81));
        return double(count_label(patch, PixelLabel::kDropout)) / patch.total();
    };
    EXPECT_EQ(fraction_at(60.0), 0.0);
    EXPECT_NEAR(fraction_at(77.5), 0.5, 0.1);
    EXPECT_GT(fraction_at(86.0), 0.99);
}

TEST(Noise, DeterministicForASeedAndAnyThreadCount) {
    const io::SensorSpec spec = kinect_v2_spec("k");
    const Mesh mesh = testing::ball_before_wall(Eigen::Vector3d(0.2, 0, 2.0), 0.6,
                                                Eigen::Vector3d(0, 0, 1.2), 0.15, 3);
    const DepthRender clean = render_depth(RenderScene(mesh), spec.depth, Pose::Identity());
    const NoiseOptions o;
    NoisyDepth a;
    {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
        a = apply_depth_noise(clean, spec.depth, traits_of(spec), o, 11);
    }
    const NoisyDepth b = apply_depth_noise(clean, spec.depth, traits_of(spec), o, 11);
    const NoisyDepth c = apply_depth_noise(clean, spec.depth, traits_of(spec), o, 12);
    EXPECT_EQ(std::memcmp(a.depth.data, b.depth.data, a.depth.total() * 4), 0);
    EXPECT_EQ(std::memcmp(a.labels.data, b.labels.data, a.labels.total()), 0);
    EXPECT_NE(std::memcmp(a.depth.data, c.depth.data, a.depth.total() * 4), 0);

    cv::Mat img1(300, 400, CV_8UC3, cv::Scalar(100, 120, 140)), img2 = img1.clone();
    apply_color_noise(img1, 2.0, 5);
    apply_color_noise(img2, 2.0, 5);
    EXPECT_EQ(cv::norm(img1, img2, cv::NORM_INF), 0.0);
    cv::Scalar mean, sd;
    cv::meanStdDev(img1, mean, sd);
    for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(sd[ch], 2.0, 0.05);
}

TEST(Noise, RejectsAbsurdOptions) {
    NoiseOptions o;
    o.flying_fraction = 1.5;
    EXPECT_THROW(o.check(), InputError);
    o = NoiseOptions{};
    o.grazing_start_deg = 86;
    EXPECT_THROW(o.check(), InputError);
    o = NoiseOptions{};
    o.outlier_rate = -0.1;
    EXPECT_THROW(o.check(), InputError);
}

}  // namespace
}  // namespace rgbd::synth
