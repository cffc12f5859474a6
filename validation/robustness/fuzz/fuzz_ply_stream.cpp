// libFuzzer target: the view stream reader (io/ply_stream.hpp) on arbitrary bytes, reading
// every document until the end of the stream or the first error.
#include <sstream>

#include "io/ply_stream.hpp"
#include "validation/robustness/fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
    rgbd::io::PlyStreamReader reader(in, "<fuzz>");
    rgbd::io::Document document;
    rgbd::fuzz::expect_clean([&] {
        while (reader.next(document)) {
        }
    });
    return 0;
}
