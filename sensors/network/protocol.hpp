// Wire format of the capture network (docs/algorithms.md §1). Two channels per node:
//  - frames: node PUSH -> hub PULL, one ZeroMQ message part per frame: a fixed 128-byte
//    little-endian header (magic, version, session, sensor id, frame index, device and node
//    time stamps, the node's send time (bytes 116-123, once reserved: 0 from older nodes),
//    image size, payload sizes, CRC-32 of header and of each payload), then the depth
//    compressed with RVL (io/rvl.hpp), then the colour as a JPEG file.
//  - control: node DEALER <-> hub ROUTER, small fixed messages (hello with the sensor's rig
//    entry as JSON, clock probes and replies, start, bye), so probes never queue behind frames.
// Parsers never throw and never read past the message: they return false with a reason, and
// the hub counts and drops the message.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace rgbd::sensors::net {

inline constexpr std::uint32_t kFrameMagic = 0x46444752;    // "RGDF"
inline constexpr std::uint32_t kControlMagic = 0x43444752;  // "RGDC"
inline constexpr std::uint16_t kProtocolVersion = 1;
inline constexpr std::size_t kFrameHeaderSize = 128;
inline constexpr std::size_t kMaxSensorId = 47;
inline constexpr std::size_t kMaxPayload = 64u << 20;  ///< 64 MiB per payload, a sanity bound

/// CRC-32 (zlib polynomial).
std::uint32_t crc32(const std::uint8_t* data, std::size_t size);

/// What a frame message carries.
enum class PayloadKind : std::uint8_t {
    kFrame = 0,  ///< depth as RVL, colour as JPEG
    kView = 1,   ///< a fused-ready view (rgbd-node --views): n points as float32 x y z (world
                 ///< frame, metres, little-endian) in the first payload, n x 3 bytes sRGB in
                 ///< the second; width x height is still the sensor's depth size
};

/// Fields of a frame header.
struct FrameHeader {
    PayloadKind kind = PayloadKind::kFrame;
    std::uint64_t session = 0;   ///< random per node run: a restart is a new session
    std::string sensor_id;       ///< at most kMaxSensorId bytes
    std::int64_t index = 0;      ///< the node's frame counter
    std::int64_t device_ns = 0;  ///< device time stamp (its own clock)
    std::int64_t node_ns = 0;    ///< capture instant in the node's clock
    /// When the node sent the message, in the node's clock (0 = not given: nodes before issue
    /// 38). sent_ns - node_ns is how far the node is behind its sensor (rgbd-capture's health
    /// check, cli/hub_health.hpp).
    std::int64_t sent_ns = 0;
    std::uint16_t width = 0, height = 0;
    std::uint32_t depth_bytes = 0, color_bytes = 0;
    std::uint32_t depth_crc = 0, color_crc = 0;
};

/// Writes header + payloads into `out` (resized; capacity reused). Computes the CRCs.
void encode_frame(FrameHeader header, const std::uint8_t* depth_rvl, std::size_t depth_bytes,
                  const std::uint8_t* color_jpeg, std::size_t color_bytes,
                  std::vector<std::uint8_t>& out);

/// A parsed frame message; payload pointers point into the message.
struct FrameView {
    FrameHeader header;
    const std::uint8_t* depth = nullptr;
    const std::uint8_t* color = nullptr;
};

/// Validates and parses a frame message (sizes, magic, version, CRCs). Returns false and the
/// reason in `error` for anything malformed or truncated.
bool parse_frame(const std::uint8_t* data, std::size_t size, FrameView& out, std::string& error);

// ------------------------------------------------------------------------------ control

enum class ControlType : std::uint8_t {
    kHello = 1,       ///< node -> hub: session, JSON {"sensor": rig entry, "rate_hz": f}
    kProbe = 2,       ///< hub -> node: seq, t0 (hub clock)
    kProbeReply = 3,  ///< node -> hub: seq, t0, t1 (node receipt), t2 (node reply)
    kStart = 4,       ///< hub -> node: start streaming; t0 = the first frame's capture instant
                      ///< in the node's clock (0 = at once), t1 = the rig's frame period (ns,
                      ///< the grid a start instant already past is moved along), JSON = what
                      ///< the node sends (empty: frames; {"views": ...}: fused-ready views,
                      ///< cli/node_views.hpp)
    kBye = 5,         ///< node -> hub: session, frames sent; the node stops
};

struct ControlMessage {
    ControlType type = ControlType::kHello;
    std::uint64_t session = 0;  ///< hello, bye
    std::uint32_t seq = 0;      ///< probe, reply
    std::int64_t t0 = 0, t1 = 0, t2 = 0;
    std::int64_t frames = 0;  ///< bye
    std::string json;         ///< hello, start
};

std::vector<std::uint8_t> encode_control(const ControlMessage& message);
bool parse_control(const std::uint8_t* data, std::size_t size, ControlMessage& out,
                   std::string& error);

}  // namespace rgbd::sensors::net
