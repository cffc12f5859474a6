// Tests of the PNG/JPEG codec (io/image_codec.hpp): every mode decodes what OpenCV's
// imgcodecs (the reference it replaces) decodes from the same bytes, bit for bit; round trips;
// the real images of ../shared/data; damaged, truncated, empty and foreign bytes fail with
// IoError; images that cannot be encoded fail with InputError.
#include "io/image_codec.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "tests/support/shared_data.hpp"
#include "toolkit/error.hpp"

namespace rgbd::io {
namespace {

cv::Mat noise(int rows, int cols, int type, unsigned seed) {
    cv::Mat m(rows, cols, type);
    cv::theRNG().state = seed;
    cv::randu(m, 0, m.depth() == CV_16U ? 65536 : 256);
    return m;
}

/// A smooth image (JPEG's blocks are exercised without noise dominating).
cv::Mat gradient(int rows, int cols) {
    cv::Mat m(rows, cols, CV_8UC3);
    for (int y = 0; y < rows; ++y)
        for (int x = 0; x < cols; ++x)
            m.at<cv::Vec3b>(y, x) = {static_cast<uchar>(x * 3), static_cast<uchar>(y * 2),
                                     static_cast<uchar>((x + y) % 256)};
    return m;
}

std::vector<std::uint8_t> cv_encode(const std::string& ext, const cv::Mat& m,
                                    const std::vector<int>& params = {}) {
    std::vector<uchar> bytes;
    EXPECT_TRUE(cv::imencode(ext, m, bytes, params));
    return {bytes.begin(), bytes.end()};
}

void expect_same(const cv::Mat& a, const cv::Mat& b, const std::string& what) {
    ASSERT_EQ(a.type(), b.type()) << what;
    ASSERT_EQ(a.size(), b.size()) << what;
    EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0) << what;
}

void expect_like_opencv(const std::vector<std::uint8_t>& bytes, const std::string& what) {
    const cv::Mat raw(1, static_cast<int>(bytes.size()), CV_8UC1,
                      const_cast<std::uint8_t*>(bytes.data()));
    expect_same(decode_image(bytes, ImageMode::kUnchanged), cv::imdecode(raw, cv::IMREAD_UNCHANGED),
                what + " unchanged");
    expect_same(decode_image(bytes, ImageMode::kColor), cv::imdecode(raw, cv::IMREAD_COLOR),
                what + " colour");
    // Grey from colour: OpenCV's PNG decoder converts inside libpng, ours with cvtColor; the
    // weights are the same, the rounding may differ by one level.
    const cv::Mat ours = decode_image(bytes, ImageMode::kGrey);
    const cv::Mat theirs = cv::imdecode(raw, cv::IMREAD_GRAYSCALE);
    ASSERT_EQ(ours.type(), theirs.type()) << what;
    EXPECT_LE(cv::norm(ours, theirs, cv::NORM_INF), 1.0) << what << " grey";
}

TEST(ImageCodec, DecodesPngsAsOpenCvDoes) {
    for (int type : {CV_8UC1, CV_8UC3, CV_8UC4, CV_16UC1, CV_16UC3})
        expect_like_opencv(cv_encode(".png", noise(37, 53, type, 7 + type)),
                           "png type " + std::to_string(type));
    // Interlaced files are not written by OpenCV; a 1-bit file is.
    expect_like_opencv(
        cv_encode(".png", noise(20, 30, CV_8UC1, 3) > 128, {cv::IMWRITE_PNG_BILEVEL, 1}),
        "1-bit png");
}

TEST(ImageCodec, DecodesJpegsAsOpenCvDoes) {
    expect_like_opencv(cv_encode(".jpg", gradient(48, 64), {cv::IMWRITE_JPEG_QUALITY, 90}),
                       "colour jpeg");
    cv::Mat grey;
    cv::cvtColor(gradient(48, 64), grey, cv::COLOR_BGR2GRAY);
    expect_like_opencv(cv_encode(".jpg", grey), "grey jpeg");
}

TEST(ImageCodec, PngRoundTripIsExactAndOpenCvReadsIt) {
    for (int type : {CV_8UC1, CV_8UC3, CV_8UC4, CV_16UC1, CV_16UC3}) {
        const cv::Mat m = noise(31, 17, type, 11 + type);
        for (int level : {0, 1, 9}) {
            const std::vector<std::uint8_t> png = encode_png(m, level);
            expect_same(decode_image(png, ImageMode::kUnchanged), m, "round trip");
            const cv::Mat raw(1, static_cast<int>(png.size()), CV_8UC1,
                              const_cast<std::uint8_t*>(png.data()));
            expect_same(cv::imdecode(raw, cv::IMREAD_UNCHANGED), m, "opencv reads ours");
        }
    }
}

TEST(ImageCodec, JpegRoundTripIsClose) {
    const cv::Mat m = gradient(64, 80);
    const std::vector<std::uint8_t> jpg = encode_jpeg(m, 95);
    const cv::Mat back = decode_image(jpg, ImageMode::kColor);
    ASSERT_EQ(back.type(), CV_8UC3);
    EXPECT_LT(cv::norm(back, m, cv::NORM_L1) / static_cast<double>(m.total() * 3), 2.0);
    // Lower quality, smaller file; encode_image picks the format from the extension.
    EXPECT_LT(encode_image("x.JPG", m, 30).size(), jpg.size());
    EXPECT_EQ(encode_image(".png", m), encode_png(m, 1));
}

TEST(ImageCodec, ReadsTheSharedCaptures) {
    const auto apc = test::shared_data("multiview/apc_realsense_f200_shelf");
    RGBD_SKIP_WITHOUT(apc);
    for (const char* name : {"frame-000000.depth.png", "frame-000000.color.png"}) {
        const std::string file = (apc / name).string();
        expect_same(read_image(file), cv::imread(file, cv::IMREAD_UNCHANGED), file);
    }
    int jpegs = 0;
    for (const auto& e :
         std::filesystem::recursive_directory_iterator(test::shared_data("multiview"))) {
        if (e.path().extension() != ".jpg" || jpegs >= 3) continue;
        ++jpegs;
        const std::string file = e.path().string();
        expect_same(read_image(file, ImageMode::kColor), cv::imread(file, cv::IMREAD_COLOR), file);
    }
    EXPECT_GT(jpegs, 0);
}

TEST(ImageCodec, DamagedBytesFailWithIoError) {
    const std::vector<std::uint8_t> png = encode_png(noise(40, 40, CV_16UC1, 5));
    const std::vector<std::uint8_t> jpg = encode_jpeg(gradient(40, 40));
    for (const auto* full : {&png, &jpg}) {
        for (std::size_t keep :
             {std::size_t{0}, std::size_t{4}, full->size() / 2, full->size() - 3}) {
            const std::vector<std::uint8_t> cut(full->begin(), full->begin() + keep);
            EXPECT_THROW(decode_image(cut, ImageMode::kUnchanged, "cut.png"), IoError) << keep;
        }
    }
    std::vector<std::uint8_t> garbage(200, 0x42);
    try {
        decode_image(garbage, ImageMode::kUnchanged, "x.png");
        FAIL() << "garbage decoded";
    } catch (const IoError& e) {
        EXPECT_NE(std::string(e.what()).find("x.png: neither PNG nor JPEG"), std::string::npos)
            << e.what();
    }
    // A PNG whose data is corrupted after the header.
    std::vector<std::uint8_t> bad = png;
    for (std::size_t i = 60; i < bad.size() - 20; ++i) bad[i] ^= 0x5A;
    EXPECT_THROW(decode_image(bad, ImageMode::kUnchanged), IoError);
    EXPECT_THROW(read_image("/nonexistent/depth.png"), IoError);
}

TEST(ImageCodec, UnencodableImagesFailWithInputError) {
    EXPECT_THROW(encode_png(cv::Mat()), InputError);
    EXPECT_THROW(encode_png(cv::Mat(4, 4, CV_32FC1)), InputError);
    EXPECT_THROW(encode_png(cv::Mat(4, 4, CV_8UC1), 10), InputError);
    EXPECT_THROW(encode_jpeg(cv::Mat(4, 4, CV_16UC1)), InputError);
    EXPECT_THROW(encode_jpeg(cv::Mat(4, 4, CV_8UC3), 0), InputError);
    EXPECT_THROW(encode_image("x.tiff", cv::Mat(4, 4, CV_8UC3)), InputError);
}

}  // namespace
}  // namespace rgbd::io
