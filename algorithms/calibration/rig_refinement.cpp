#include "algorithms/calibration/rig_refinement.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "toolkit/error.hpp"

namespace rgbd::calibration {

cv::Mat combined_depth(const std::vector<cv::Mat>& depths, double agree_m, double agree_ratio) {
    RGBD_CHECK(!depths.empty(), "combined depth: no depth images");
    RGBD_CHECK(
        std::isfinite(agree_m) && agree_m >= 0 && std::isfinite(agree_ratio) && agree_ratio >= 0,
        "combined depth: tolerances must be >= 0");
    for (const cv::Mat& d : depths)
        RGBD_CHECK(d.type() == CV_32FC1 && d.size() == depths.front().size(),
                   "combined depth: every image must be CV_32FC1 of the same size");
    if (depths.size() == 1) return depths.front().clone();
    const std::size_t n = depths.size();
    cv::Mat out(depths.front().size(), CV_32FC1);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    tbb::parallel_for(0, out.rows, [&](int r) {
        std::vector<float> values;
        values.reserve(n);
        float* dst = out.ptr<float>(r);
        for (int c = 0; c < out.cols; ++c) {
            values.clear();
            for (const cv::Mat& d : depths) {
                const float z = d.ptr<float>(r)[c];
                if (std::isfinite(z) && z > 0) values.push_back(z);
            }
            dst[c] = nan;
            if (2 * values.size() <= n) continue;
            const std::size_t m = values.size();
            std::sort(values.begin(), values.end());
            const float median = m % 2 ? values[m / 2] : 0.5f * (values[m / 2 - 1] + values[m / 2]);
            const double tolerance = agree_m + agree_ratio * median;
            std::size_t agree = 0;
            double sum = 0.0;
            for (float z : values)
                if (std::abs(z - median) <= tolerance) {
                    ++agree;
                    sum += z;
                }
            if (2 * agree > n) dst[c] = static_cast<float>(sum / static_cast<double>(agree));
        }
    });
    return out;
}

registration::MultiViewOptions rig_refinement_options(std::size_t fixed_view, std::uint64_t seed) {
    registration::MultiViewOptions o;
    o.fixed_view = fixed_view;
    o.seed = seed;
    o.pairwise = false;
    o.global_registration = false;
    o.icp.max_distance_factors = {25.0, 12.0, 6.0, 3.0, 1.5, 1.0};
    o.rounds = static_cast<int>(o.icp.max_distance_factors.size());
    o.voxel_factor = 0.8;
    o.max_points_per_view = 0;
    o.fail_fitness = 0.1;
    o.warn_fitness = 0.15;
    o.max_rotation_deg = 20.0;
    o.max_translation_m = 0.2;
    return o;
}

}  // namespace rgbd::calibration
