// Ring-by-ring dilation of an image from its covered pixels: each round, every uncovered pixel
// with a covered 8-neighbour takes the mean of those neighbours and becomes covered. The atlas
// pads a chart from its own texels with it (atlas.cpp, CV_8UC3, rounded integer mean) and the
// seam levelling extends a chart's colour corrections past its faces (seam_levelling.cpp,
// CV_32FC3, float mean). Internal to algorithms/ (not installed).
#pragma once

#include <opencv2/core.hpp>
#include <type_traits>

namespace rgbd::internal {

/// Dilates `image` (3 channels of `Channel`: uchar for CV_8UC3, float for CV_32FC3) from the
/// pixels where `covered` (CV_8U, same size; changed in place) is non-zero, for at most `rings`
/// rounds (fewer when a round adds nothing). Round k reads only pixels covered before it, so
/// the result does not depend on the scan order. uchar means are rounded half up in integers,
/// float means are the float sum divided by the count (cv::Vec / int).
template <typename Channel>
void dilate_covered(cv::Mat& image, cv::Mat& covered, int rings) {
    using Pixel = cv::Vec<Channel, 3>;
    using Sum = cv::Vec<std::conditional_t<std::is_integral_v<Channel>, int, float>, 3>;
    CV_Assert(image.type() == cv::traits::Type<Pixel>::value && covered.type() == CV_8U &&
              covered.size() == image.size());
    for (int ring = 0; ring < rings; ++ring) {
        cv::Mat next = covered.clone();
        bool grown = false;
        for (int y = 0; y < image.rows; ++y)
            for (int x = 0; x < image.cols; ++x) {
                if (covered.at<uchar>(y, x)) continue;
                Sum sum = Sum::all(0);
                int count = 0;
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx) {
                        const int yy = y + dy, xx = x + dx;
                        if (yy < 0 || xx < 0 || yy >= image.rows || xx >= image.cols ||
                            !covered.at<uchar>(yy, xx))
                            continue;
                        const Pixel& p = image.at<Pixel>(yy, xx);
                        for (int ch = 0; ch < 3; ++ch) sum[ch] += p[ch];
                        ++count;
                    }
                if (count == 0) continue;
                Pixel& q = image.at<Pixel>(y, x);
                if constexpr (std::is_integral_v<Channel>) {
                    for (int ch = 0; ch < 3; ++ch)
                        q[ch] = static_cast<Channel>((sum[ch] + count / 2) / count);
                } else {
                    q = sum / count;  // cv::Vec's division by an int, as the seam levelling had
                }
                next.at<uchar>(y, x) = 1;
                grown = true;
            }
        covered = next;
        if (!grown) break;
    }
}

}  // namespace rgbd::internal
