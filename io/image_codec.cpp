#include "io/image_codec.hpp"

// jpeglib.h needs <cstdio> before it, jerror.h needs jpeglib.h.
// clang-format off
#include <cstdio>
#include <jpeglib.h>
#include <jerror.h>
// clang-format on
#include <png.h>

#include <algorithm>
#include <cctype>
#include <csetjmp>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <opencv2/imgproc.hpp>

#include "io/internal/depth_png.hpp"
#include "toolkit/error.hpp"

namespace rgbd::io {

namespace {

// ---------------------------------------------------------------- PNG

struct PngSource {
    const std::uint8_t* data;
    std::size_t size, offset;
};

void png_read_memory(png_structp png, png_bytep out, png_size_t n) {
    auto* src = static_cast<PngSource*>(png_get_io_ptr(png));
    if (n > src->size - src->offset) png_error(png, "the file ends early (truncated)");
    std::memcpy(out, src->data + src->offset, n);
    src->offset += n;
}
[[noreturn]] void png_throw(png_structp, png_const_charp message) { throw IoError(message); }
void png_quiet(png_structp, png_const_charp) {}

bool is_png(const std::uint8_t* data, std::size_t size) {
    return size >= 8 && png_sig_cmp(data, 0, 8) == 0;
}

cv::Mat decode_png(const std::uint8_t* data, std::size_t size, ImageMode mode) {
    png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, nullptr, png_throw, png_quiet);
    if (!png) throw IoError("out of memory");
    png_infop info = png_create_info_struct(png);
    cv::Mat image;
    try {
        if (!info) throw IoError("out of memory");
        PngSource src{data, size, 0};
        png_set_read_fn(png, &src, png_read_memory);
        png_read_info(png, info);
        const png_uint_32 width = png_get_image_width(png, info);
        const png_uint_32 height = png_get_image_height(png, info);
        const int colour = png_get_color_type(png, info);
        const int depth = png_get_bit_depth(png, info);
        if (width == 0 || height == 0 || width > (1u << 15) || height > (1u << 15))
            throw IoError("absurd size " + std::to_string(width) + "x" + std::to_string(height));
        // The same transformations as OpenCV's PNG decoder: everything below 8 bits expanded,
        // palettes and tRNS to colour or alpha, 16 bits kept only when asked for as stored.
        if (colour == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
        if (colour == PNG_COLOR_TYPE_GRAY && depth < 8) png_set_expand_gray_1_2_4_to_8(png);
        if (png_get_valid(png, info, PNG_INFO_tRNS)) png_set_tRNS_to_alpha(png);
        png_set_packing(png);
        const bool grey_file =
            colour == PNG_COLOR_TYPE_GRAY ||
            (colour == PNG_COLOR_TYPE_GRAY_ALPHA && mode != ImageMode::kUnchanged);
        if (mode != ImageMode::kUnchanged) {
            if (depth == 16) png_set_strip_16(png);
            png_set_strip_alpha(png);
        }
        if (mode == ImageMode::kColor && grey_file) png_set_gray_to_rgb(png);
        if (mode == ImageMode::kUnchanged && colour == PNG_COLOR_TYPE_GRAY_ALPHA)
            png_set_gray_to_rgb(png);  // OpenCV: grey + alpha is BGRA
        png_set_bgr(png);
        if (depth == 16 && mode == ImageMode::kUnchanged) png_set_swap(png);  // to native order
        png_set_interlace_handling(png);
        png_read_update_info(png, info);
        const int channels = png_get_channels(png, info);
        const int out_depth = png_get_bit_depth(png, info);
        const int type = CV_MAKETYPE(out_depth == 16 ? CV_16U : CV_8U, channels);
        image.create(static_cast<int>(height), static_cast<int>(width), type);
        std::vector<png_bytep> rows(height);
        for (png_uint_32 y = 0; y < height; ++y) rows[y] = image.ptr<png_byte>(static_cast<int>(y));
        png_read_image(png, rows.data());
        png_read_end(png, nullptr);
    } catch (...) {
        png_destroy_read_struct(&png, &info, nullptr);
        throw;
    }
    png_destroy_read_struct(&png, &info, nullptr);
    if (mode == ImageMode::kGrey && image.channels() == 3)
        cv::cvtColor(image, image, cv::COLOR_BGR2GRAY);
    return image;
}

void png_append(png_structp png, png_bytep data, png_size_t size) {
    auto* out = static_cast<std::vector<std::uint8_t>*>(png_get_io_ptr(png));
    out->insert(out->end(), data, data + size);
}
void png_no_flush(png_structp) {}

/// PNG of an image of a type encode_png accepts into `out` (cleared; its capacity reused), zlib
/// `level`; with `up_filter` one fixed row filter (Up) instead of libpng's adaptive per-row
/// search. IoError "PNG encoding failed: ..." when libpng fails.
void write_png(const cv::Mat& image, int level, bool up_filter, std::vector<std::uint8_t>& out) {
    const int depth = image.depth(), channels = image.channels();
    out.clear();
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, png_throw, png_quiet);
    if (!png) throw IoError("PNG encoding failed: out of memory");
    png_infop info = png_create_info_struct(png);
    try {
        if (!info) throw IoError("out of memory");
        png_set_write_fn(png, &out, png_append, png_no_flush);
        png_set_compression_level(png, level);
        if (up_filter) png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_UP);
        const int colour = channels == 1   ? PNG_COLOR_TYPE_GRAY
                           : channels == 3 ? PNG_COLOR_TYPE_RGB
                                           : PNG_COLOR_TYPE_RGB_ALPHA;
        png_set_IHDR(png, info, static_cast<png_uint_32>(image.cols),
                     static_cast<png_uint_32>(image.rows), depth == CV_16U ? 16 : 8, colour,
                     PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
        png_write_info(png, info);
        png_set_bgr(png);
        if (depth == CV_16U) png_set_swap(png);  // PNG stores 16-bit samples big-endian
        for (int y = 0; y < image.rows; ++y)
            png_write_row(png, const_cast<png_bytep>(image.ptr<png_byte>(y)));
        png_write_end(png, info);
    } catch (const IoError& e) {
        png_destroy_write_struct(&png, &info);
        throw IoError(std::string("PNG encoding failed: ") + e.what());
    }
    png_destroy_write_struct(&png, &info);
}

// ---------------------------------------------------------------- JPEG

struct JpegError {
    jpeg_error_mgr base;
    std::jmp_buf jump;
    char message[JMSG_LENGTH_MAX];
};

void jpeg_on_error(j_common_ptr info) {
    auto* err = reinterpret_cast<JpegError*>(info->err);
    (*info->err->format_message)(info, err->message);
    std::longjmp(err->jump, 1);
}
// Warnings are ignored as OpenCV ignores them, except a premature end of the data: libjpeg
// fills the missing rows with grey, and a truncated file is damaged.
void jpeg_on_message(j_common_ptr info, int level) {
    if (level < 0 && info->err->msg_code == JWRN_JPEG_EOF) (*info->err->error_exit)(info);
}

/// libjpeg's error manager with the handlers above (errors longjmp to err.jump).
jpeg_error_mgr* jpeg_errors(JpegError& err) {
    jpeg_error_mgr* mgr = jpeg_std_error(&err.base);
    mgr->error_exit = jpeg_on_error;
    mgr->emit_message = jpeg_on_message;
    return mgr;
}

bool is_jpeg(const std::uint8_t* data, std::size_t size) {
    return size >= 3 && data[0] == 0xFF && data[1] == 0xD8 && data[2] == 0xFF;
}

// No C++ object with a destructor lives in the frames a longjmp crosses: the decoder works
// into a matrix allocated before setjmp and reports failure by a flag.
bool decode_jpeg_into(const std::uint8_t* data, std::size_t size, ImageMode mode, cv::Mat& image,
                      char* message) {
    jpeg_decompress_struct info;
    JpegError err;
    info.err = jpeg_errors(err);
    if (setjmp(err.jump)) {
        std::memcpy(message, err.message, JMSG_LENGTH_MAX);
        jpeg_destroy_decompress(&info);
        return false;
    }
    jpeg_create_decompress(&info);
    jpeg_mem_src(&info, data, static_cast<unsigned long>(size));
    jpeg_read_header(&info, TRUE);
    const bool grey_file = info.num_components == 1;
    const bool grey = mode == ImageMode::kGrey || (mode == ImageMode::kUnchanged && grey_file);
    if (!grey && (info.jpeg_color_space == JCS_CMYK || info.jpeg_color_space == JCS_YCCK)) {
        std::snprintf(message, JMSG_LENGTH_MAX, "CMYK JPEG is not supported (convert to RGB)");
        jpeg_destroy_decompress(&info);
        return false;
    }
    info.out_color_space = grey ? JCS_GRAYSCALE : JCS_EXT_BGR;
    jpeg_start_decompress(&info);
    if (info.output_width > (1u << 15) || info.output_height > (1u << 15)) {
        std::snprintf(message, JMSG_LENGTH_MAX, "absurd size %ux%u", info.output_width,
                      info.output_height);
        jpeg_destroy_decompress(&info);
        return false;
    }
    image.create(static_cast<int>(info.output_height), static_cast<int>(info.output_width),
                 grey ? CV_8UC1 : CV_8UC3);
    while (info.output_scanline < info.output_height) {
        JSAMPROW row = image.ptr<JSAMPLE>(static_cast<int>(info.output_scanline));
        jpeg_read_scanlines(&info, &row, 1);
    }
    jpeg_finish_decompress(&info);
    jpeg_destroy_decompress(&info);
    return true;
}

bool encode_jpeg_into(const cv::Mat& image, int quality, unsigned char** buffer,
                      unsigned long* size, char* message) {
    jpeg_compress_struct info;
    JpegError err;
    info.err = jpeg_errors(err);
    if (setjmp(err.jump)) {
        std::memcpy(message, err.message, JMSG_LENGTH_MAX);
        jpeg_destroy_compress(&info);
        return false;
    }
    jpeg_create_compress(&info);
    jpeg_mem_dest(&info, buffer, size);
    info.image_width = static_cast<JDIMENSION>(image.cols);
    info.image_height = static_cast<JDIMENSION>(image.rows);
    info.input_components = image.channels();
    info.in_color_space = image.channels() == 1 ? JCS_GRAYSCALE : JCS_EXT_BGR;
    jpeg_set_defaults(&info);
    jpeg_set_quality(&info, quality, TRUE);
    jpeg_start_compress(&info, TRUE);
    while (info.next_scanline < info.image_height) {
        JSAMPROW row =
            const_cast<JSAMPROW>(image.ptr<JSAMPLE>(static_cast<int>(info.next_scanline)));
        jpeg_write_scanlines(&info, &row, 1);
    }
    jpeg_finish_compress(&info);
    jpeg_destroy_compress(&info);
    return true;
}

std::string lower_extension(const std::string& path) {
    const auto dot = path.find_last_of('.');
    std::string ext = dot == std::string::npos ? path : path.substr(dot);
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return ext;
}

}  // namespace

cv::Mat decode_image(const std::uint8_t* data, std::size_t size, ImageMode mode,
                     const std::string& what) {
    const auto fail = [&](const std::string& why) {
        throw IoError(what.empty() ? why : what + ": " + why);
    };
    if (is_png(data, size)) {
        try {
            return decode_png(data, size, mode);
        } catch (const IoError& e) {
            fail(std::string("damaged PNG: ") + e.what());
        }
    }
    if (is_jpeg(data, size)) {
        cv::Mat image;
        char message[JMSG_LENGTH_MAX] = {};
        if (!decode_jpeg_into(data, size, mode, image, message))
            fail(std::string("damaged JPEG: ") + message);
        return image;
    }
    fail(size == 0 ? "empty file" : "neither PNG nor JPEG (by its signature)");
    return {};
}

std::vector<std::uint8_t> read_file_bytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(path + ": cannot open");
    std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                    std::istreambuf_iterator<char>());
    if (in.bad()) throw IoError(path + ": read error");
    return bytes;
}

cv::Mat read_image(const std::string& path, ImageMode mode) {
    return decode_image(read_file_bytes(path), mode, path);
}

std::vector<std::uint8_t> encode_png(const cv::Mat& image, int level) {
    const int depth = image.depth(), channels = image.channels();
    RGBD_CHECK(!image.empty(), "encode_png: empty image");
    RGBD_CHECK((depth == CV_8U && (channels == 1 || channels == 3 || channels == 4)) ||
                   (depth == CV_16U && (channels == 1 || channels == 3)),
               "encode_png: the image must be 8-bit grey/BGR/BGRA or 16-bit grey/BGR");
    RGBD_CHECK(level >= 0 && level <= 9, "encode_png: level must be 0..9");
    std::vector<std::uint8_t> out;
    write_png(image, level, false, out);
    return out;
}

void internal::encode_depth_png(const cv::Mat& depth, int level, std::vector<std::uint8_t>& out) {
    if (depth.type() != CV_16UC1 || depth.empty())
        throw InputError("encode_depth_png: depth must be a non-empty CV_16UC1 image");
    if (level < 0 || level > 9) throw InputError("encode_depth_png: level must be 0..9");
    write_png(depth, level, true, out);
}

std::vector<std::uint8_t> encode_jpeg(const cv::Mat& image, int quality) {
    RGBD_CHECK(!image.empty(), "encode_jpeg: empty image");
    RGBD_CHECK(image.depth() == CV_8U && (image.channels() == 1 || image.channels() == 3),
               "encode_jpeg: the image must be 8-bit grey or BGR");
    RGBD_CHECK(quality >= 1 && quality <= 100, "encode_jpeg: quality must be 1..100");
    unsigned char* buffer = nullptr;
    unsigned long size = 0;
    char message[JMSG_LENGTH_MAX] = {};
    const bool ok = encode_jpeg_into(image, quality, &buffer, &size, message);
    std::vector<std::uint8_t> out;
    if (ok) out.assign(buffer, buffer + size);
    std::free(buffer);
    if (!ok) throw IoError(std::string("JPEG encoding failed: ") + message);
    return out;
}

std::vector<std::uint8_t> encode_image(const std::string& path_or_extension, const cv::Mat& image,
                                       int level_or_quality) {
    const std::string ext = lower_extension(path_or_extension);
    if (ext == ".png") return encode_png(image, level_or_quality < 0 ? 1 : level_or_quality);
    if (ext == ".jpg" || ext == ".jpeg")
        return encode_jpeg(image, level_or_quality < 0 ? 95 : level_or_quality);
    throw InputError(path_or_extension + ": images are written as PNG or JPEG (.png, .jpg)");
}

}  // namespace rgbd::io
