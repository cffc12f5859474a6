#include "algorithms/texture/colour_adjustment.hpp"

#include <Eigen/Dense>
#include <cmath>

#include "toolkit/error.hpp"

namespace rgbd::texture {

void AdjustOptions::check() const {
    RGBD_CHECK(std::isfinite(prior_weight) && prior_weight > 0 && prior_weight <= 1e6,
               "texture: colour adjustment prior weight must be in (0, 1e6]");
    RGBD_CHECK(std::isfinite(outlier_levels) && outlier_levels > 0,
               "texture: colour adjustment outlier threshold must be > 0");
    RGBD_CHECK(max_points >= 1, "texture: colour adjustment needs max_points >= 1");
}

std::vector<ColourGain> adjust_colours(const render::RenderScene& scene,
                                       const std::vector<TextureView>& views,
                                       const FaceQuality& quality, const AdjustOptions& options,
                                       Report& report) {
    options.check();
    const int nv = quality.views, nf = quality.faces;
    std::vector<ColourGain> gains(nv);
    report["enabled"] = options.enabled;
    if (!options.enabled || nv < 2) return gains;
    // Faces seen by two or more views, evenly thinned to max_points.
    std::vector<int> shared;
    for (int f = 0; f < nf; ++f) {
        int seen = 0;
        for (int v = 0; v < nv && seen < 2; ++v) seen += quality.at(v, f) > 0;
        if (seen >= 2) shared.push_back(f);
    }
    const std::size_t step = std::max<std::size_t>(1, shared.size() / options.max_points + 1);
    // Normal equations per channel; unknowns (g_0, o_0, g_1, o_1, ...), colours in [0, 1].
    const int n = 2 * nv;
    std::vector<Eigen::MatrixXd> a(3, Eigen::MatrixXd::Zero(n, n));
    std::vector<Eigen::VectorXd> b(3, Eigen::VectorXd::Zero(n));
    std::size_t points = 0, pairs = 0, rejected = 0;
    std::vector<std::pair<int, Eigen::Vector3d>> seen;
    for (std::size_t i = 0; i < shared.size(); i += step) {
        const int f = shared[i];
        const auto& t = scene.triangles()[f];
        const Eigen::Vector3d cw =
            (scene.vertices()[t[0]] + scene.vertices()[t[1]] + scene.vertices()[t[2]]) / 3.0;
        seen.clear();
        for (int v = 0; v < nv; ++v) {
            if (!(quality.at(v, f) > 0)) continue;
            const Eigen::Vector2d uv =
                views[v].intrinsics.project(views[v].world_from_camera.inverse() * cw);
            seen.emplace_back(v, sample_bgr(views[v].image, uv.x(), uv.y()) / 255.0);
        }
        ++points;
        for (std::size_t p = 0; p < seen.size(); ++p)
            for (std::size_t q = p + 1; q < seen.size(); ++q) {
                const auto& [va, ca] = seen[p];
                const auto& [vb, cb] = seen[q];
                if ((ca - cb).cwiseAbs().maxCoeff() * 255.0 > options.outlier_levels) {
                    ++rejected;
                    continue;
                }
                ++pairs;
                for (int ch = 0; ch < 3; ++ch) {
                    // residual = r . x with r = (+ca at g_a, +1 at o_a, -cb at g_b, -1 at o_b).
                    const int idx[4] = {2 * va, 2 * va + 1, 2 * vb, 2 * vb + 1};
                    const double r[4] = {ca[ch], 1.0, -cb[ch], -1.0};
                    for (int x = 0; x < 4; ++x)
                        for (int y = 0; y < 4; ++y) a[ch](idx[x], idx[y]) += r[x] * r[y];
                }
            }
    }
    const double w = options.prior_weight * std::max(1.0, static_cast<double>(pairs) / nv);
    Report per_view = Report::array();
    for (int ch = 0; ch < 3; ++ch) {
        for (int v = 0; v < nv; ++v) {
            a[ch](2 * v, 2 * v) += w;  // (g - 1)^2
            b[ch][2 * v] += w;
            a[ch](2 * v + 1, 2 * v + 1) += w;  // o^2
        }
        // Gauge: the mean gain is 1 and the mean offset 0 (Lagrange multipliers), so that the
        // pairwise terms cannot shrink every gain together.
        Eigen::MatrixXd kkt = Eigen::MatrixXd::Zero(n + 2, n + 2);
        Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n + 2);
        kkt.topLeftCorner(n, n) = a[ch];
        rhs.head(n) = b[ch];
        for (int v = 0; v < nv; ++v) {
            kkt(n, 2 * v) = kkt(2 * v, n) = 1.0;
            kkt(n + 1, 2 * v + 1) = kkt(2 * v + 1, n + 1) = 1.0;
        }
        rhs[n] = nv;
        const Eigen::VectorXd x = kkt.partialPivLu().solve(rhs);
        for (int v = 0; v < nv; ++v) {
            gains[v].gain[ch] = x[2 * v];
            gains[v].offset[ch] = x[2 * v + 1] * 255.0;
        }
    }
    for (int v = 0; v < nv; ++v) {
        const auto& g = gains[v];
        per_view.push_back({{"view", views[v].name},
                            {"gain_rgb", {g.gain[2], g.gain[1], g.gain[0]}},
                            {"offset_rgb", {g.offset[2], g.offset[1], g.offset[0]}}});
    }
    report["points"] = points;
    report["pairs"] = pairs;
    report["pairs_rejected"] = rejected;
    report["views"] = per_view;
    return gains;
}

Eigen::Vector3d sample_bgr(const cv::Mat& bgr, double u, double v) {
    const int x0 = std::clamp(static_cast<int>(std::floor(u)), 0, bgr.cols - 2);
    const int y0 = std::clamp(static_cast<int>(std::floor(v)), 0, bgr.rows - 2);
    const double fx = std::clamp(u - x0, 0.0, 1.0), fy = std::clamp(v - y0, 0.0, 1.0);
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    const double w[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
    const cv::Vec3b p[4] = {bgr.at<cv::Vec3b>(y0, x0), bgr.at<cv::Vec3b>(y0, x0 + 1),
                            bgr.at<cv::Vec3b>(y0 + 1, x0), bgr.at<cv::Vec3b>(y0 + 1, x0 + 1)};
    for (int i = 0; i < 4; ++i)
        for (int ch = 0; ch < 3; ++ch) c[ch] += w[i] * p[i][ch];
    return c;
}

void apply_gain(cv::Mat& bgr, const ColourGain& gain) {
    if ((gain.gain.array() == 1.0).all() && (gain.offset.array() == 0.0).all()) return;
    // A lookup table per channel (the map is affine in each channel separately).
    cv::Mat lut(1, 256, CV_8UC3);
    for (int i = 0; i < 256; ++i)
        for (int ch = 0; ch < 3; ++ch)
            lut.at<cv::Vec3b>(0, i)[ch] =
                cv::saturate_cast<uchar>(gain.gain[ch] * i + gain.offset[ch]);
    cv::LUT(bgr, lut, bgr);
}

}  // namespace rgbd::texture
