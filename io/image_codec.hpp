// PNG and JPEG images read and written with libpng and libjpeg-turbo directly.
//
// Why not cv::imread: Debian's libopencv-imgcodecs links GDAL, GDCM, OpenEXR and ~130 other
// shared libraries whose loading and static initialisers cost every process about 80 ms before
// main (measured: a program that links it starts in 91 ms, one that does not in 8 ms;
// validation/results/2026-11-29-startup-without-imgcodecs-*.md). Every tool of the pipe and
// every capture reader pays it; the capture formats are PNG (depth, colour, labels) and JPEG
// (colour), which these two libraries decode exactly as OpenCV does (OpenCV uses them).
//
// Images are OpenCV matrices with OpenCV's conventions: colour channels in BGR(A) order,
// 16-bit samples in native order.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace rgbd::io {

/// What a decoder returns.
enum class ImageMode {
    kUnchanged,  ///< as stored: 1, 3 or 4 channels (grey, BGR, BGRA), 8 or 16 bits per sample
    kColor,      ///< 8-bit BGR, 3 channels (grey replicated, alpha dropped, 16 bits scaled)
    kGrey,       ///< 8-bit, 1 channel (colour converted with OpenCV's weights)
};

/// Decodes a PNG or a JPEG (recognised by its signature, not by a file name) from memory.
/// Throws IoError "WHAT: why" (`what` a file name or a description; "why" alone when empty)
/// when the bytes are neither format or are damaged (a truncated file included). Bit depths below 8
/// and palettes are expanded.
cv::Mat decode_image(const std::uint8_t* data, std::size_t size, ImageMode mode,
                     const std::string& what = "image");
inline cv::Mat decode_image(const std::vector<std::uint8_t>& bytes, ImageMode mode,
                            const std::string& what = "image") {
    return decode_image(bytes.data(), bytes.size(), mode, what);
}

/// The whole file `path`; IoError naming it when it cannot be opened or read.
std::vector<std::uint8_t> read_file_bytes(const std::string& path);

/// Reads and decodes the PNG or JPEG file `path`. IoError (naming the file) when it is
/// missing, unreadable, not PNG or JPEG, or damaged.
cv::Mat read_image(const std::string& path, ImageMode mode = ImageMode::kUnchanged);

/// PNG of an 8-bit (1, 3 or 4 channels: grey, BGR, BGRA) or 16-bit (1 or 3 channels) image,
/// zlib `level` 0-9. InputError for another type or an empty image.
std::vector<std::uint8_t> encode_png(const cv::Mat& image, int level = 3);

/// Baseline JPEG of an 8-bit grey or BGR image at `quality` 1-100. InputError otherwise.
std::vector<std::uint8_t> encode_jpeg(const cv::Mat& image, int quality = 95);

/// Encodes by the extension of `path_or_extension` (".png", ".jpg" or ".jpeg", any case;
/// `level_or_quality` < 0: PNG level 1, as OpenCV's default, JPEG quality 95). InputError for
/// another extension.
std::vector<std::uint8_t> encode_image(const std::string& path_or_extension, const cv::Mat& image,
                                       int level_or_quality = -1);

}  // namespace rgbd::io
