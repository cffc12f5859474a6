// Exemplar-based colour inpainting (Criminisi et al. 2004, §12.2) against the true texture:
// stripes and checks with a hole cut out, where copying exemplars reproduces the pattern and
// Telea's fast marching (OpenCV, as the toolkit uses it) blurs it; pixels outside both masks
// are never read nor written; an image without a complete source patch; bad input.
#include "algorithms/holes/exemplar_inpaint.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <opencv2/imgproc.hpp>
#include <opencv2/photo.hpp>

#include "toolkit/error.hpp"

namespace {

using rgbd::holes::exemplar_inpaint;
using rgbd::holes::ExemplarOptions;

const cv::Vec3b kDark(30, 40, 140), kLight(230, 200, 60);

cv::Mat texture(int rows, int cols, const std::function<bool(int, int)>& light) {
    cv::Mat img(rows, cols, CV_8UC3);
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) img.at<cv::Vec3b>(r, c) = light(r, c) ? kLight : kDark;
    return img;
}

/// Mean absolute difference per channel over the mask's pixels.
double error(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask) {
    double sum = 0;
    int n = 0;
    for (int r = 0; r < a.rows; ++r)
        for (int c = 0; c < a.cols; ++c) {
            if (!mask.at<std::uint8_t>(r, c)) continue;
            const cv::Vec3b x = a.at<cv::Vec3b>(r, c), y = b.at<cv::Vec3b>(r, c);
            for (int k = 0; k < 3; ++k) sum += std::abs(int(x[k]) - int(y[k]));
            n += 3;
        }
    return sum / n;
}

/// Standard deviation of the first channel over the mask (the pattern's contrast).
double contrast(const cv::Mat& img, const cv::Mat& mask) {
    cv::Scalar mean, dev;
    cv::meanStdDev(img, mean, dev, mask);
    return dev[0];
}

struct Result {
    double exemplar_error, telea_error, exemplar_contrast, telea_contrast, true_contrast;
};

Result compare(const cv::Mat& truth, const cv::Rect& hole_box) {
    cv::Mat hole = cv::Mat::zeros(truth.size(), CV_8U);
    hole(hole_box).setTo(255);
    const cv::Mat source = 255 - hole;
    cv::Mat damaged = truth.clone();
    damaged.setTo(cv::Scalar(0, 0, 0), hole);
    cv::Mat ours = damaged.clone();
    const auto stats = exemplar_inpaint(ours, hole, source);
    EXPECT_EQ(stats.unfilled, 0);
    EXPECT_EQ(stats.filled, hole_box.area());
    cv::Mat telea;
    cv::inpaint(damaged, hole, telea, 5.0, cv::INPAINT_TELEA);
    Result r{error(ours, truth, hole), error(telea, truth, hole), contrast(ours, hole),
             contrast(telea, hole), contrast(truth, hole)};
    std::cout << "exemplar error " << r.exemplar_error << ", Telea " << r.telea_error
              << "; contrast true " << r.true_contrast << ", exemplar " << r.exemplar_contrast
              << ", Telea " << r.telea_contrast << ", patches " << stats.patches << "\n";
    // Nothing outside the hole changes.
    EXPECT_EQ(error(ours, truth, source), 0.0);
    return r;
}

TEST(ExemplarInpaint, ReproducesStripesThatTeleaBlurs) {
    // Vertical stripes 4 px wide, a 20 x 20 hole: the stripes run through it.
    const cv::Mat truth = texture(96, 96, [](int, int c) { return (c / 4) % 2 == 0; });
    const Result r = compare(truth, cv::Rect(38, 38, 20, 20));
    EXPECT_LT(r.exemplar_error, 0.25 * r.telea_error);
    EXPECT_LT(r.exemplar_error, 10.0);  // of a 200-level contrast
    EXPECT_GT(r.exemplar_contrast, 0.9 * r.true_contrast);
    EXPECT_LT(r.telea_contrast, 0.8 * r.true_contrast);  // the blur the exemplars avoid
}

TEST(ExemplarInpaint, ReproducesAChecker) {
    const cv::Mat truth = texture(100, 120, [](int r, int c) { return ((r / 6) + (c / 6)) % 2; });
    const Result r = compare(truth, cv::Rect(50, 40, 24, 18));
    EXPECT_LT(r.exemplar_error, 0.5 * r.telea_error);
    EXPECT_GT(r.exemplar_contrast, 0.85 * r.true_contrast);
}

TEST(ExemplarInpaint, PixelsOutsideBothMasksAreNeitherReadNorWritten) {
    // Stripes on the left half (the source), a hole in it, a bright green right half that is
    // neither source nor hole (outside the object): no green may appear in the hole.
    cv::Mat img = texture(60, 80, [](int, int c) { return (c / 3) % 2 == 0; });
    cv::Mat source = cv::Mat::zeros(img.size(), CV_8U), hole = source.clone();
    source(cv::Rect(0, 0, 40, 60)).setTo(255);
    img(cv::Rect(40, 0, 40, 60)).setTo(cv::Scalar(0, 255, 0));
    const cv::Rect box(28, 20, 12, 14);  // touching the outside region
    source(box).setTo(0);
    hole(box).setTo(255);
    img(box).setTo(cv::Scalar(0, 0, 0));
    const cv::Mat before = img.clone();
    const auto stats = exemplar_inpaint(img, hole, source);
    EXPECT_EQ(stats.unfilled, 0);
    for (int r = 0; r < img.rows; ++r)
        for (int c = 0; c < img.cols; ++c) {
            const cv::Vec3b v = img.at<cv::Vec3b>(r, c);
            if (hole.at<std::uint8_t>(r, c))
                EXPECT_TRUE(v == kDark || v == kLight) << r << "," << c;
            else
                EXPECT_EQ(v, before.at<cv::Vec3b>(r, c));
        }
}

TEST(ExemplarInpaint, PatchesShrinkToATheBandOfKnownPixels) {
    // 4 known rows of stripes: no 9 x 9 patch fits, 3 x 3 ones do and continue the stripes.
    const cv::Mat truth = texture(20, 30, [](int, int c) { return (c / 2) % 2 == 0; });
    cv::Mat img = truth.clone();
    cv::Mat source = cv::Mat::zeros(img.size(), CV_8U), hole = source.clone();
    source(cv::Rect(0, 0, 30, 4)).setTo(255);
    hole(cv::Rect(0, 4, 30, 16)).setTo(255);
    img.setTo(cv::Scalar(0, 0, 0), hole);
    const auto stats = exemplar_inpaint(img, hole, source);
    EXPECT_EQ(stats.patch, 3);
    EXPECT_EQ(stats.unfilled, 0);
    EXPECT_EQ(stats.filled, 30 * 16);
    EXPECT_EQ(error(img, truth, hole), 0.0);
}

TEST(ExemplarInpaint, NoCompleteSourcePatchLeavesTheHoleAsItIs) {
    cv::Mat img(20, 20, CV_8UC3, cv::Scalar(10, 20, 30));
    cv::Mat source = cv::Mat::zeros(img.size(), CV_8U), hole = source.clone();
    source(cv::Rect(0, 0, 20, 2)).setTo(255);  // 2 rows: not even a 3 x 3 patch fits
    hole(cv::Rect(0, 2, 20, 18)).setTo(255);
    const auto stats = exemplar_inpaint(img, hole, source);
    EXPECT_EQ(stats.filled, 0);
    EXPECT_EQ(stats.unfilled, 20 * 18);
    // An empty hole is nothing to do.
    EXPECT_EQ(exemplar_inpaint(img, cv::Mat::zeros(img.size(), CV_8U), source).patches, 0);
}

TEST(ExemplarInpaint, BadInputIsAnError) {
    cv::Mat img(10, 10, CV_8UC3, cv::Scalar(0, 0, 0));
    const cv::Mat mask = cv::Mat::zeros(img.size(), CV_8U);
    cv::Mat gray(10, 10, CV_8U, cv::Scalar(0));
    EXPECT_THROW(exemplar_inpaint(gray, mask, mask), rgbd::InputError);
    EXPECT_THROW(exemplar_inpaint(img, cv::Mat::zeros(5, 5, CV_8U), mask), rgbd::InputError);
    EXPECT_THROW(exemplar_inpaint(img, mask, cv::Mat::zeros(img.size(), CV_32F)), rgbd::InputError);
    for (int patch : {2, 1, 8, 53}) {
        ExemplarOptions o;
        o.patch = patch;
        EXPECT_THROW(exemplar_inpaint(img, mask, mask, o), rgbd::InputError) << patch;
    }
    for (double w : {0.5, std::nan(""), 1e9}) {
        ExemplarOptions o;
        o.search_window = w;
        EXPECT_THROW(exemplar_inpaint(img, mask, mask, o), rgbd::InputError) << w;
    }
}

}  // namespace

// The patches are compared in CIELab computed by the toolkit (OpenCV builds its Lab tables on
// first use, 0.1 s of one core): over a grid of 8-bit colours (every 15th level per channel:
// black, white, the greys, the primaries) it matches the CIE formulas evaluated in double
// precision, and OpenCV's cv::COLOR_RGB2Lab on float RGB in [0, 1] to within the 0.3 units of
// OpenCV's own interpolated tables.
TEST(ExemplarInpaint, LabIsTheCieFormula) {
    const auto exact = [](const cv::Vec3b& c) {
        const auto linear = [](double v) {
            v /= 255.0;
            return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
        };
        const double r = linear(c[0]), g = linear(c[1]), b = linear(c[2]);
        const double x = (0.412453 * r + 0.357580 * g + 0.180423 * b) / 0.950456;
        const double y = 0.212671 * r + 0.715160 * g + 0.072169 * b;
        const double z = (0.019334 * r + 0.119193 * g + 0.950227 * b) / 1.088754;
        const auto f = [](double t) {
            return t > 0.008856 ? std::cbrt(t) : 7.787 * t + 16.0 / 116;
        };
        const double l = y > 0.008856 ? 116 * f(y) - 16 : 903.3 * y;
        return cv::Vec3d(l, 500 * (f(x) - f(y)), 200 * (f(y) - f(z)));
    };
    cv::Mat rgb(18 * 18, 18, CV_8UC3);
    for (int r = 0; r < 18; ++r)
        for (int g = 0; g < 18; ++g)
            for (int b = 0; b < 18; ++b)
                rgb.at<cv::Vec3b>(r * 18 + g, b) = cv::Vec3b(r * 15, g * 15, b * 15);
    cv::Mat lab;
    rgb.convertTo(lab, CV_32FC3, 1.0 / 255.0);
    cv::cvtColor(lab, lab, cv::COLOR_RGB2Lab);
    double to_exact = 0, to_opencv = 0;
    for (int row = 0; row < rgb.rows; ++row)
        for (int col = 0; col < rgb.cols; ++col) {
            const cv::Vec3b c = rgb.at<cv::Vec3b>(row, col);
            const cv::Vec3f ours = rgbd::holes::detail::srgb_to_lab(c);
            const cv::Vec3d truth = exact(c);
            const cv::Vec3f theirs = lab.at<cv::Vec3f>(row, col);
            for (int k = 0; k < 3; ++k) {
                to_exact = std::max(to_exact, std::abs(ours[k] - truth[k]));
                to_opencv = std::max(to_opencv, double(std::abs(ours[k] - theirs[k])));
            }
        }
    std::cout << "largest Lab difference: to the formula " << to_exact << ", to OpenCV "
              << to_opencv << "\n";
    EXPECT_LT(to_exact, 1e-3);
    EXPECT_LT(to_opencv, 0.5);
    // Known values: white is L 100, a = b = 0; black is 0; sRGB red (255, 0, 0) is L 53.24,
    // a 80.09, b 67.20.
    const cv::Vec3f white = rgbd::holes::detail::srgb_to_lab({255, 255, 255});
    EXPECT_NEAR(white[0], 100.0, 0.01);
    EXPECT_NEAR(white[1], 0.0, 0.01);
    EXPECT_NEAR(white[2], 0.0, 0.01);
    EXPECT_NEAR(rgbd::holes::detail::srgb_to_lab({0, 0, 0})[0], 0.0, 1e-6);
    const cv::Vec3f red = rgbd::holes::detail::srgb_to_lab({255, 0, 0});
    EXPECT_NEAR(red[0], 53.24, 0.01);
    EXPECT_NEAR(red[1], 80.09, 0.01);
    EXPECT_NEAR(red[2], 67.20, 0.01);
}
