#include "io/rvl.hpp"

#include <string>

#include "toolkit/error.hpp"

namespace rgbd::io {

namespace {

class NibbleWriter {
public:
    explicit NibbleWriter(std::uint8_t* out) : out_(out) {}
    void encode(std::uint32_t value) {
        do {
            std::uint32_t nibble = value & 7u;
            value >>= 3;
            if (value) nibble |= 8u;
            word_ = (word_ << 4) | nibble;
            if (++nibbles_ == 8) flush_word();
        } while (value);
    }
    std::size_t finish() {
        if (nibbles_) {
            word_ <<= 4 * (8 - nibbles_);
            flush_word();
        }
        return bytes_;
    }

private:
    void flush_word() {
        out_[bytes_ + 0] = static_cast<std::uint8_t>(word_);
        out_[bytes_ + 1] = static_cast<std::uint8_t>(word_ >> 8);
        out_[bytes_ + 2] = static_cast<std::uint8_t>(word_ >> 16);
        out_[bytes_ + 3] = static_cast<std::uint8_t>(word_ >> 24);
        bytes_ += 4;
        word_ = 0;
        nibbles_ = 0;
    }
    std::uint8_t* out_;
    std::size_t bytes_ = 0;
    std::uint32_t word_ = 0;
    int nibbles_ = 0;
};

class NibbleReader {
public:
    NibbleReader(const std::uint8_t* data, std::size_t size, const char* what)
        : data_(data), size_(size), what_(what) {}
    std::uint32_t decode() {
        std::uint32_t value = 0;
        int shift = 0;
        for (;;) {
            const std::uint32_t nibble = next();
            if (shift > 30 || (shift == 30 && (nibble & 7u) > 3u))
                fail("a run length or value does not fit 32 bits");
            value |= (nibble & 7u) << shift;
            if (!(nibble & 8u)) return value;
            shift += 3;
        }
    }
    /// Everything read; the rest of the last word must be zero padding.
    void finish() {
        if (pos_ != size_) fail("trailing bytes after the last pixel");
        if (nibbles_ > 0 && (word_ >> (4 * (8 - nibbles_))) != 0) fail("non-zero padding");
    }
    [[noreturn]] void fail(const std::string& why) const {
        throw InputError(std::string(what_) + ": corrupt RVL depth: " + why);
    }

private:
    std::uint32_t next() {
        if (nibbles_ == 0) {
            if (pos_ + 4 > size_) fail("truncated");
            word_ = static_cast<std::uint32_t>(data_[pos_]) |
                    static_cast<std::uint32_t>(data_[pos_ + 1]) << 8 |
                    static_cast<std::uint32_t>(data_[pos_ + 2]) << 16 |
                    static_cast<std::uint32_t>(data_[pos_ + 3]) << 24;
            pos_ += 4;
            nibbles_ = 8;
        }
        const std::uint32_t nibble = word_ >> 28;
        word_ <<= 4;
        --nibbles_;
        return nibble;
    }
    const std::uint8_t* data_;
    std::size_t size_;
    const char* what_;
    std::size_t pos_ = 0;
    std::uint32_t word_ = 0;
    int nibbles_ = 0;
};

}  // namespace

std::size_t rvl_max_compressed_size(std::size_t pixels) {
    // A pixel costs at most 6 nibbles (a 17-bit zig-zag delta) plus its share of the two run
    // lengths; runs alternate, so two run codes of at most 11 nibbles per non-zero pixel bound
    // everything generously: 4 bytes per pixel plus the run codes of one extra run pair.
    return pixels * 4 + 32;
}

std::size_t rvl_compress(const std::uint16_t* depth, std::size_t pixels,
                         std::vector<std::uint8_t>& out) {
    out.resize(rvl_max_compressed_size(pixels));
    NibbleWriter writer(out.data());
    const std::uint16_t* in = depth;
    const std::uint16_t* const end = depth + pixels;
    std::int32_t previous = 0;
    while (in != end) {
        std::uint32_t zeros = 0;
        for (; in != end && *in == 0; ++in) ++zeros;
        writer.encode(zeros);
        std::uint32_t nonzeros = 0;
        for (const std::uint16_t* p = in; p != end && *p != 0; ++p) ++nonzeros;
        writer.encode(nonzeros);
        for (std::uint32_t i = 0; i < nonzeros; ++i) {
            const std::int32_t current = *in++;
            const std::int32_t delta = current - previous;
            writer.encode(static_cast<std::uint32_t>((delta << 1) ^ (delta >> 31)));
            previous = current;
        }
    }
    const std::size_t size = writer.finish();
    out.resize(size);
    return size;
}

void rvl_decompress(const std::uint8_t* data, std::size_t size, std::uint16_t* depth,
                    std::size_t pixels, const char* what) {
    NibbleReader reader(data, size, what);
    if (size % 4 != 0) reader.fail("size is not a multiple of 4 bytes");
    std::size_t filled = 0;
    std::int32_t previous = 0;
    while (filled < pixels) {
        const std::uint32_t zeros = reader.decode();
        if (zeros > pixels - filled) reader.fail("a zero run goes past the last pixel");
        for (std::uint32_t i = 0; i < zeros; ++i) depth[filled++] = 0;
        const std::uint32_t nonzeros = reader.decode();
        if (nonzeros > pixels - filled) reader.fail("a pixel run goes past the last pixel");
        if (zeros == 0 && nonzeros == 0 && filled < pixels) reader.fail("an empty run pair");
        for (std::uint32_t i = 0; i < nonzeros; ++i) {
            const std::uint32_t code = reader.decode();
            const std::int64_t delta =
                static_cast<std::int64_t>(code >> 1) ^ -static_cast<std::int64_t>(code & 1u);
            const std::int64_t current = previous + delta;
            if (current <= 0 || current > 65535) reader.fail("a pixel value out of 1..65535");
            depth[filled++] = static_cast<std::uint16_t>(current);
            previous = static_cast<std::int32_t>(current);
        }
    }
    reader.finish();
}

}  // namespace rgbd::io
