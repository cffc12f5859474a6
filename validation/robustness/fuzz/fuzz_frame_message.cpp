// libFuzzer target: the capture network's messages (sensors/network/protocol.hpp) as the hub
// receives them: parse_frame and, for a valid frame, the RVL depth payload decoded to the
// rig's depth size (what the hub does; here a 64x48 sensor); parse_control on the same bytes. The
// parsers must never throw; the decoder throws only InputError.
#include <string>
#include <vector>

#include "io/rvl.hpp"
#include "sensors/network/protocol.hpp"
#include "validation/robustness/fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    namespace net = rgbd::sensors::net;
    std::string error;
    net::FrameView frame;
    if (net::parse_frame(data, size, frame, error)) {
        const std::size_t pixels = 64 * 48;
        std::vector<std::uint16_t> depth(pixels);
        rgbd::fuzz::expect_clean([&] {
            rgbd::io::rvl_decompress(frame.depth, frame.header.depth_bytes, depth.data(), pixels,
                                     "<fuzz frame>");
        });
    }
    net::ControlMessage control;
    net::parse_control(data, size, control, error);
    return 0;
}
