#include "io/internal/depth_png.hpp"

#include <png.h>

#include <string>

#include "toolkit/error.hpp"

namespace rgbd::io::internal {

namespace {

void append(png_structp png, png_bytep data, png_size_t size) {
    auto* out = static_cast<std::vector<std::uint8_t>*>(png_get_io_ptr(png));
    out->insert(out->end(), data, data + size);
}
void no_flush(png_structp) {}
[[noreturn]] void on_error(png_structp, png_const_charp message) {
    throw IoError(std::string("PNG encoding failed: ") + message);
}
void on_warning(png_structp, png_const_charp) {}

}  // namespace

void encode_depth_png(const cv::Mat& depth, int level, std::vector<std::uint8_t>& out) {
    if (depth.type() != CV_16UC1 || depth.empty())
        throw InputError("encode_depth_png: depth must be a non-empty CV_16UC1 image");
    if (level < 0 || level > 9) throw InputError("encode_depth_png: level must be 0..9");
    thread_local std::vector<std::uint8_t> row;
    row.resize(static_cast<std::size_t>(depth.cols) * 2);
    out.clear();
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, on_error, on_warning);
    if (!png) throw IoError("PNG encoding failed: out of memory");
    png_infop info = png_create_info_struct(png);
    try {
        if (!info) throw IoError("PNG encoding failed: out of memory");
        png_set_write_fn(png, &out, append, no_flush);
        png_set_compression_level(png, level);
        png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_UP);
        png_set_IHDR(png, info, static_cast<png_uint_32>(depth.cols),
                     static_cast<png_uint_32>(depth.rows), 16, PNG_COLOR_TYPE_GRAY,
                     PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
        png_write_info(png, info);
        for (int y = 0; y < depth.rows; ++y) {
            const std::uint16_t* in = depth.ptr<std::uint16_t>(y);
            for (int x = 0; x < depth.cols; ++x) {  // PNG stores 16-bit samples big-endian
                row[2 * static_cast<std::size_t>(x)] = static_cast<std::uint8_t>(in[x] >> 8);
                row[2 * static_cast<std::size_t>(x) + 1] = static_cast<std::uint8_t>(in[x]);
            }
            png_write_row(png, row.data());
        }
        png_write_end(png, info);
    } catch (...) {
        png_destroy_write_struct(&png, &info);
        throw;
    }
    png_destroy_write_struct(&png, &info);
}

}  // namespace rgbd::io::internal
