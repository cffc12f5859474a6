// libFuzzer target: the RVL depth decoder (io/rvl.hpp). The first two bytes give the pixel
// count (up to 65535), the rest is the compressed data.
#include <vector>

#include "io/rvl.hpp"
#include "validation/robustness/fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size < 2) return 0;
    const std::size_t pixels = data[0] | (std::size_t{data[1]} << 8);
    std::vector<std::uint16_t> depth(pixels);
    rgbd::fuzz::expect_clean(
        [&] { rgbd::io::rvl_decompress(data + 2, size - 2, depth.data(), pixels, "<fuzz>"); });
    return 0;
}
