#include "algorithms/holes/exemplar_inpaint.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <utility>
#include <vector>

#include "toolkit/error.hpp"
#include "toolkit/srgb.hpp"

namespace rgbd::holes {

void ExemplarOptions::check() const {
    RGBD_CHECK(patch >= 3 && patch <= 51 && patch % 2 == 1,
               "exemplar inpainting: the patch side must be odd, in [3, 51] pixels");
    check_range("exemplar inpainting: the search window", search_window, Range::closed(1, 100),
                "hole boxes");
}

namespace detail {

cv::Vec3f srgb_to_lab(const cv::Vec3b& rgb) {
    const std::array<float, 256>& linear = srgb_linear_table();
    // sRGB to XYZ (D65), rows X and Z divided by the white point's X and Z.
    constexpr float kXn = 0.950456f, kZn = 1.088754f;
    const float r = linear[rgb[0]], g = linear[rgb[1]], b = linear[rgb[2]];
    const float x = (0.412453f * r + 0.357580f * g + 0.180423f * b) / kXn;
    const float y = 0.212671f * r + 0.715160f * g + 0.072169f * b;
    const float z = (0.019334f * r + 0.119193f * g + 0.950227f * b) / kZn;
    constexpr float kEdge = 0.008856f;  // (6/29)^3
    const auto f = [](float t) { return t > kEdge ? std::cbrt(t) : 7.787f * t + 16.0f / 116.0f; };
    const float fx = f(x), fy = f(y), fz = f(z);
    const float l = y > kEdge ? 116.0f * fy - 16.0f : 903.3f * y;
    return {l, 500.0f * (fx - fy), 200.0f * (fy - fz)};
}

}  // namespace detail

namespace {

enum Region : std::uint8_t { kOutside = 0, kSource = 1, kFilled = 2, kHole = 3 };

struct Best {
    double ssd = std::numeric_limits<double>::infinity();
    int index = -1;
    bool better(double s, int i) const { return s < ssd || (s == ssd && i < index); }
};

}  // namespace

ExemplarStats exemplar_inpaint(cv::Mat& rgb, const cv::Mat& target, const cv::Mat& source,
                               const ExemplarOptions& options) {
    options.check();
    RGBD_CHECK(rgb.type() == CV_8UC3, "exemplar inpainting: the image must be 8-bit, 3 channels");
    RGBD_CHECK(target.type() == CV_8U && source.type() == CV_8U,
               "exemplar inpainting: the masks must be 8-bit, 1 channel");
    RGBD_CHECK(target.size() == rgb.size() && source.size() == rgb.size(),
               "exemplar inpainting: the masks must have the image's size");
    ExemplarStats stats;
    const int rows = rgb.rows, cols = rgb.cols;
    const int n = rows * cols;
    if (n == 0 || cv::countNonZero(target) == 0) return stats;

    std::vector<std::uint8_t> region(static_cast<std::size_t>(n), kOutside);
    std::vector<float> confidence(static_cast<std::size_t>(n), 0.0f);
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            const int i = r * cols + c;
            if (target.at<std::uint8_t>(r, c)) {
                region[i] = kHole;
            } else if (source.at<std::uint8_t>(r, c)) {
                region[i] = kSource;
                confidence[i] = 1.0f;
            }
        }
    // CIELab, L scaled to [0, 255] so that the data term's 1/255 normalises as in the paper.
    std::vector<cv::Vec3f> px(static_cast<std::size_t>(n));
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            cv::Vec3f v = detail::srgb_to_lab(rgb.at<cv::Vec3b>(r, c));
            v[0] *= 2.55f;
            px[r * cols + c] = v;
        }
    // Centres of complete source patches (inside the image, every pixel a source pixel). When
    // the image holds none (a thin band of known pixels, like the rim of the head top), the
    // patch shrinks by 2 until one fits [M].
    cv::Mat src = cv::Mat::zeros(rows, cols, CV_8U);
    for (int i = 0; i < n; ++i)
        if (region[i] == kSource) src.data[i] = 255;
    std::vector<int> candidates;
    int side = options.patch;
    for (;; side -= 2) {
        const int h = side / 2;
        cv::Mat src_ok;
        cv::erode(src, src_ok, cv::Mat::ones(side, side, CV_8U), cv::Point(-1, -1), 1,
                  cv::BORDER_CONSTANT, cv::Scalar(0));
        for (int r = h; r < rows - h; ++r)
            for (int c = h; c < cols - h; ++c)
                if (src_ok.at<std::uint8_t>(r, c)) candidates.push_back(r * cols + c);
        if (!candidates.empty() || side <= 3) break;
    }
    stats.patch = side;
    const int half = side / 2;
    // Candidates: every source pixel whose patch lies inside the image (complete patches and
    // partial ones, which the search accepts when they hold every pixel to copy) [M]: in a
    // sparsely known image (the cylinder of a bust) complete patches are rare and far away.
    candidates.clear();
    for (int r = half; r < rows - half; ++r)
        for (int c = half; c < cols - half; ++c)
            if (region[r * cols + c] == kSource) candidates.push_back(r * cols + c);
    // Hole components and their search windows.
    cv::Mat labels, boxes, centroids;
    cv::connectedComponentsWithStats(target != 0, labels, boxes, centroids, 8, CV_32S);
    auto window_of = [&](int label) {
        const int x = boxes.at<int>(label, cv::CC_STAT_LEFT),
                  y = boxes.at<int>(label, cv::CC_STAT_TOP);
        const int w = boxes.at<int>(label, cv::CC_STAT_WIDTH),
                  h = boxes.at<int>(label, cv::CC_STAT_HEIGHT);
        const int gw =
            std::max(static_cast<int>(std::ceil(w * (options.search_window - 1) / 2)), side);
        const int gh =
            std::max(static_cast<int>(std::ceil(h * (options.search_window - 1) / 2)), side);
        return cv::Rect(cv::Point(std::max(x - gw, 0), std::max(y - gh, 0)),
                        cv::Point(std::min(x + w + gw, cols), std::min(y + h + gh, rows)));
    };

    auto valid = [&](int i) { return region[i] == kSource || region[i] == kFilled; };
    auto is_hole = [&](int r, int c) {
        return r >= 0 && r < rows && c >= 0 && c < cols && region[r * cols + c] == kHole;
    };
    // Gradient of L at a valid pixel, from its valid neighbours (central, else one-sided).
    auto gradient = [&](int r, int c, double& gx, double& gy) {
        auto diff = [&](int r0, int c0, int r1, int c1, double& g) {
            const bool a = r0 >= 0 && r0 < rows && c0 >= 0 && c0 < cols && valid(r0 * cols + c0);
            const bool b = r1 >= 0 && r1 < rows && c1 >= 0 && c1 < cols && valid(r1 * cols + c1);
            const double m = px[r * cols + c][0];
            if (a && b)
                g = (px[r1 * cols + c1][0] - px[r0 * cols + c0][0]) / 2;
            else if (b)
                g = px[r1 * cols + c1][0] - m;
            else if (a)
                g = m - px[r0 * cols + c0][0];
            else
                g = 0;
        };
        diff(r, c - 1, r, c + 1, gx);
        diff(r - 1, c, r + 1, c, gy);
    };

    std::vector<std::pair<int, int>> offsets;  // (dr, dc) of the target patch's valid pixels
    std::vector<std::pair<int, int>> missing;  // ... and of its hole pixels
    offsets.reserve(static_cast<std::size_t>(side) * side);
    int remaining = cv::countNonZero(target);
    while (remaining > 0) {
        // The front: hole pixels with a valid 4-neighbour. Highest priority C(p) (D(p) + eps):
        // the small eps [M] keeps the onion-peel order by confidence where the data term is 0
        // (flat colour).
        double best_p = -1;
        int best_i = -1;
        double best_c = 0;
        for (int r = 0; r < rows; ++r)
            for (int c = 0; c < cols; ++c) {
                const int i = r * cols + c;
                if (region[i] != kHole) continue;
                const bool front = (c > 0 && valid(i - 1)) || (c + 1 < cols && valid(i + 1)) ||
                                   (r > 0 && valid(i - cols)) || (r + 1 < rows && valid(i + cols));
                if (!front) continue;
                double conf = 0, gbest = -1, gx = 0, gy = 0;
                for (int dr = -half; dr <= half; ++dr)
                    for (int dc = -half; dc <= half; ++dc) {
                        const int r2 = r + dr, c2 = c + dc;
                        if (r2 < 0 || r2 >= rows || c2 < 0 || c2 >= cols) continue;
                        const int j = r2 * cols + c2;
                        if (!valid(j)) continue;
                        conf += confidence[j];
                        double ax, ay;
                        gradient(r2, c2, ax, ay);
                        if (ax * ax + ay * ay > gbest) gbest = ax * ax + ay * ay, gx = ax, gy = ay;
                    }
                conf /= double(side * side);
                // Front normal: Sobel of the hole indicator.
                double nx = 0, ny = 0;
                for (int dr = -1; dr <= 1; ++dr)
                    for (int dc = -1; dc <= 1; ++dc) {
                        if (!is_hole(r + dr, c + dc)) continue;
                        const double w = (dr == 0 || dc == 0) ? 2.0 : 1.0;
                        nx += dc * w;
                        ny += dr * w;
                    }
                const double nn = std::hypot(nx, ny);
                const double data = nn > 0 ? std::abs(-gy * nx + gx * ny) / nn / 255.0 : 0.0;
                const double p = conf * (data + 1e-3);
                if (p > best_p) best_p = p, best_i = i, best_c = conf;
            }
        if (best_i < 0) break;  // hole pixels no valid pixel reaches
        const int pr = best_i / cols, pc = best_i % cols;
        offsets.clear();
        for (int dr = -half; dr <= half; ++dr)
            for (int dc = -half; dc <= half; ++dc) {
                const int r2 = pr + dr, c2 = pc + dc;
                if (r2 < 0 || r2 >= rows || c2 < 0 || c2 >= cols) continue;
                if (valid(r2 * cols + c2)) offsets.emplace_back(dr, dc);
            }
        missing.clear();
        for (int dr = -half; dr <= half; ++dr)
            for (int dc = -half; dc <= half; ++dc) {
                const int r2 = pr + dr, c2 = pc + dc;
                if (r2 >= 0 && r2 < rows && c2 >= 0 && c2 < cols && region[r2 * cols + c2] == kHole)
                    missing.emplace_back(dr, dc);
            }
        // Source patch: every pixel to copy a source pixel; compared over the target's known
        // pixels that are source pixels there too (at least half of them), mean squared
        // difference.
        const double n_valid = double(offsets.size());
        auto search = [&](const cv::Rect& window) {
            auto body = [&](const tbb::blocked_range<std::size_t>& range, Best best) {
                for (std::size_t k = range.begin(); k != range.end(); ++k) {
                    const int s = candidates[k];
                    const int sr = s / cols, sc = s % cols;
                    if (!window.contains(cv::Point(sc, sr))) continue;
                    bool ok = true;
                    for (const auto& [dr, dc] : missing)
                        if (region[(sr + dr) * cols + sc + dc] != kSource) {
                            ok = false;
                            break;
                        }
                    if (!ok) continue;
                    double ssd = 0;
                    int compared = 0;
                    for (const auto& [dr, dc] : offsets) {
                        const int si = (sr + dr) * cols + sc + dc;
                        if (region[si] != kSource) continue;
                        const cv::Vec3f d = px[si] - px[(pr + dr) * cols + pc + dc];
                        ssd += double(d[0]) * d[0] + double(d[1]) * d[1] + double(d[2]) * d[2];
                        ++compared;
                        if (ssd > best.ssd * n_valid) {
                            ok = false;
                            break;
                        }
                    }
                    if (!ok || compared == 0 || 2 * compared < n_valid) continue;
                    const double score = ssd / compared;
                    if (best.better(score, s)) best.ssd = score, best.index = s;
                }
                return best;
            };
            return tbb::parallel_reduce(
                tbb::blocked_range<std::size_t>(0, candidates.size(), 512), Best{}, body,
                [](const Best& a, const Best& b) { return a.better(b.ssd, b.index) ? b : a; });
        };
        Best best = search(window_of(labels.at<int>(pr, pc)));
        if (best.index < 0) {
            ++stats.window_widened;
            best = search(cv::Rect(0, 0, cols, rows));
        }
        if (best.index < 0) break;  // no complete source patch anywhere
        const int sr = best.index / cols, sc = best.index % cols;
        for (int dr = -half; dr <= half; ++dr)
            for (int dc = -half; dc <= half; ++dc) {
                const int r2 = pr + dr, c2 = pc + dc;
                if (r2 < 0 || r2 >= rows || c2 < 0 || c2 >= cols) continue;
                const int j = r2 * cols + c2;
                if (region[j] != kHole) continue;
                const int s = (sr + dr) * cols + sc + dc;
                rgb.at<cv::Vec3b>(r2, c2) = rgb.at<cv::Vec3b>(sr + dr, sc + dc);
                px[j] = px[s];
                region[j] = kFilled;
                confidence[j] = static_cast<float>(best_c);
                ++stats.filled;
                --remaining;
            }
        ++stats.patches;
    }
    stats.unfilled = remaining;
    return stats;
}

}  // namespace rgbd::holes
