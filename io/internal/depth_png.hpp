// Fast 16-bit greyscale PNG encoding for depth images (io/image_codec.cpp's PNG writer): one
// fixed row filter (Up) instead of libpng's adaptive per-row filter search that encode_png and
// cv::imencode use, which makes recording about three times cheaper per frame (the capture hub
// writes 240 depth frames a second). The files are ordinary PNGs; io::read_image and
// cv::imread read them bit for bit.
// See also: io/capture_folder.hpp (CaptureWriter::add_encoded_frame).
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

namespace rgbd::io::internal {

/// Encodes a CV_16UC1 image as PNG into `out` (resized; capacity reused) with zlib level
/// `level` (0-9). Throws IoError when libpng fails.
void encode_depth_png(const cv::Mat& depth, int level, std::vector<std::uint8_t>& out);

}  // namespace rgbd::io::internal
