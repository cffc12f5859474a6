// RVL: fast lossless compression of 16-bit depth images (A. D. Wilson, "Fast Lossless Depth
// Image Compression", ISS 2017). Runs of zeros and of non-zero pixels are coded as run lengths;
// non-zero pixels as the zig-zag coded difference to the previous non-zero pixel; every number
// with a variable-length code of 3-bit nibbles plus a continuation bit, packed eight nibbles to
// a 32-bit word (stored little-endian, so the byte stream is portable).
// Used for depth in the capture network's frame messages (sensors/network/protocol.hpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace rgbd::io {

/// Bytes that rvl_compress may need for `pixels` pixels (the worst case, a bound).
std::size_t rvl_max_compressed_size(std::size_t pixels);

/// Compresses `pixels` 16-bit values into `out` (resized to the compressed size; its capacity
/// is reused, so a caller that keeps `out` between frames does not allocate after the first).
/// Returns the compressed size in bytes (a multiple of 4).
std::size_t rvl_compress(const std::uint16_t* depth, std::size_t pixels,
                         std::vector<std::uint8_t>& out);

/// Decompresses exactly `pixels` values from `size` bytes into `depth`. Throws InputError
/// (naming `what`) when the data is truncated, has trailing bytes, or decodes to anything but
/// exactly `pixels` values in 0..65535; `depth` content is unspecified then.
void rvl_decompress(const std::uint8_t* data, std::size_t size, std::uint16_t* depth,
                    std::size_t pixels, const char* what = "RVL data");

}  // namespace rgbd::io
