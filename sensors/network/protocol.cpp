#include "sensors/network/protocol.hpp"

#include <zlib.h>

#include <algorithm>
#include <cstring>

namespace rgbd::sensors::net {

namespace {

void put_u16(std::uint8_t* p, std::uint16_t v) {
    p[0] = static_cast<std::uint8_t>(v);
    p[1] = static_cast<std::uint8_t>(v >> 8);
}
void put_u32(std::uint8_t* p, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
void put_u64(std::uint8_t* p, std::uint64_t v) {
    for (int i = 0; i < 8; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
std::uint16_t get_u16(const std::uint8_t* p) {
    return static_cast<std::uint16_t>(p[0] | p[1] << 8);
}
std::uint32_t get_u32(const std::uint8_t* p) {
    std::uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= static_cast<std::uint32_t>(p[i]) << (8 * i);
    return v;
}
std::uint64_t get_u64(const std::uint8_t* p) {
    std::uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(p[i]) << (8 * i);
    return v;
}

// Frame header layout (offsets in bytes).
constexpr std::size_t kOffMagic = 0, kOffVersion = 4, kOffHeaderSize = 6, kOffSession = 8,
                      kOffIndex = 16, kOffDevice = 24, kOffNode = 32, kOffWidth = 40,
                      kOffHeight = 42, kOffDepthBytes = 44, kOffColorBytes = 48, kOffDepthCrc = 52,
                      kOffColorCrc = 56, kOffIdLength = 60, kOffId = 64, kOffKind = 112,
                      kOffSent = 116, kOffHeaderCrc = 124;
static_assert(kOffId + kMaxSensorId + 1 <= kOffKind);
static_assert(kOffKind < kOffSent && kOffSent + 8 <= kOffHeaderCrc);

}  // namespace

std::uint32_t crc32(const std::uint8_t* data, std::size_t size) {
    uLong crc = ::crc32(0L, Z_NULL, 0);
    while (size > 0) {
        const uInt chunk = static_cast<uInt>(std::min<std::size_t>(size, 1u << 30));
        crc = ::crc32(crc, data, chunk);
        data += chunk;
        size -= chunk;
    }
    return static_cast<std::uint32_t>(crc);
}

void encode_frame(FrameHeader h, const std::uint8_t* depth_rvl, std::size_t depth_bytes,
                  const std::uint8_t* color_jpeg, std::size_t color_bytes,
                  std::vector<std::uint8_t>& out) {
    h.depth_bytes = static_cast<std::uint32_t>(depth_bytes);
    h.color_bytes = static_cast<std::uint32_t>(color_bytes);
    h.depth_crc = crc32(depth_rvl, depth_bytes);
    h.color_crc = crc32(color_jpeg, color_bytes);
    out.resize(kFrameHeaderSize + depth_bytes + color_bytes);
    std::uint8_t* p = out.data();
    std::memset(p, 0, kFrameHeaderSize);
    put_u32(p + kOffMagic, kFrameMagic);
    put_u16(p + kOffVersion, kProtocolVersion);
    put_u16(p + kOffHeaderSize, static_cast<std::uint16_t>(kFrameHeaderSize));
    put_u64(p + kOffSession, h.session);
    put_u64(p + kOffIndex, static_cast<std::uint64_t>(h.index));
    put_u64(p + kOffDevice, static_cast<std::uint64_t>(h.device_ns));
    put_u64(p + kOffNode, static_cast<std::uint64_t>(h.node_ns));
    put_u64(p + kOffSent, static_cast<std::uint64_t>(h.sent_ns));
    put_u16(p + kOffWidth, h.width);
    put_u16(p + kOffHeight, h.height);
    put_u32(p + kOffDepthBytes, h.depth_bytes);
    put_u32(p + kOffColorBytes, h.color_bytes);
    put_u32(p + kOffDepthCrc, h.depth_crc);
    put_u32(p + kOffColorCrc, h.color_crc);
    const std::size_t id_length = std::min(h.sensor_id.size(), kMaxSensorId);
    p[kOffIdLength] = static_cast<std::uint8_t>(id_length);
    std::memcpy(p + kOffId, h.sensor_id.data(), id_length);
    p[kOffKind] = static_cast<std::uint8_t>(h.kind);
    put_u32(p + kOffHeaderCrc, crc32(p, kOffHeaderCrc));
    if (depth_bytes) std::memcpy(p + kFrameHeaderSize, depth_rvl, depth_bytes);
    if (color_bytes) std::memcpy(p + kFrameHeaderSize + depth_bytes, color_jpeg, color_bytes);
}

bool parse_frame(const std::uint8_t* data, std::size_t size, FrameView& out, std::string& error) {
    if (size < kFrameHeaderSize) {
        error = "shorter than a frame header (" + std::to_string(size) + " bytes)";
        return false;
    }
    if (get_u32(data + kOffMagic) != kFrameMagic) {
        error = "bad magic";
        return false;
    }
    if (get_u16(data + kOffVersion) != kProtocolVersion ||
        get_u16(data + kOffHeaderSize) != kFrameHeaderSize) {
        error = "unsupported protocol version " + std::to_string(get_u16(data + kOffVersion));
        return false;
    }
    if (get_u32(data + kOffHeaderCrc) != crc32(data, kOffHeaderCrc)) {
        error = "header checksum mismatch";
        return false;
    }
    FrameHeader& h = out.header;
    h.session = get_u64(data + kOffSession);
    h.index = static_cast<std::int64_t>(get_u64(data + kOffIndex));
    h.device_ns = static_cast<std::int64_t>(get_u64(data + kOffDevice));
    h.node_ns = static_cast<std::int64_t>(get_u64(data + kOffNode));
    h.sent_ns = static_cast<std::int64_t>(get_u64(data + kOffSent));
    h.width = get_u16(data + kOffWidth);
    h.height = get_u16(data + kOffHeight);
    h.depth_bytes = get_u32(data + kOffDepthBytes);
    h.color_bytes = get_u32(data + kOffColorBytes);
    h.depth_crc = get_u32(data + kOffDepthCrc);
    h.color_crc = get_u32(data + kOffColorCrc);
    const std::size_t id_length = data[kOffIdLength];
    if (id_length == 0 || id_length > kMaxSensorId) {
        error = "bad sensor id length";
        return false;
    }
    h.sensor_id.assign(reinterpret_cast<const char*>(data + kOffId), id_length);
    if (data[kOffKind] > static_cast<std::uint8_t>(PayloadKind::kView)) {
        error = "unknown payload kind " + std::to_string(data[kOffKind]);
        return false;
    }
    h.kind = static_cast<PayloadKind>(data[kOffKind]);
    if (h.width == 0 || h.height == 0 || h.depth_bytes > kMaxPayload ||
        h.color_bytes > kMaxPayload) {
        error = "bad image size or payload size";
        return false;
    }
    if (size != kFrameHeaderSize + std::size_t{h.depth_bytes} + h.color_bytes) {
        error = "size " + std::to_string(size) + " does not match the header (" +
                std::to_string(kFrameHeaderSize + std::size_t{h.depth_bytes} + h.color_bytes) +
                "): truncated or padded";
        return false;
    }
    out.depth = data + kFrameHeaderSize;
    out.color = out.depth + h.depth_bytes;
    if (crc32(out.depth, h.depth_bytes) != h.depth_crc) {
        error = "depth checksum mismatch";
        return false;
    }
    if (crc32(out.color, h.color_bytes) != h.color_crc) {
        error = "colour checksum mismatch";
        return false;
    }
    return true;
}

// ------------------------------------------------------------------------------ control

namespace {
constexpr std::size_t kControlFixed = 48;  // magic, version, type, pad, session, seq, t0..t2, n
}

std::vector<std::uint8_t> encode_control(const ControlMessage& m) {
    std::vector<std::uint8_t> out(kControlFixed + m.json.size(), 0);
    std::uint8_t* p = out.data();
    put_u32(p, kControlMagic);
    put_u16(p + 4, kProtocolVersion);
    p[6] = static_cast<std::uint8_t>(m.type);
    put_u64(p + 8, m.session);
    put_u32(p + 16, m.seq);
    put_u64(p + 20, static_cast<std::uint64_t>(m.t0));
    put_u64(p + 28, static_cast<std::uint64_t>(m.t1));
    put_u64(p + 36, static_cast<std::uint64_t>(m.t2));
    put_u32(p + 44, static_cast<std::uint32_t>(m.frames));
    if (!m.json.empty()) std::memcpy(p + kControlFixed, m.json.data(), m.json.size());
    return out;
}

bool parse_control(const std::uint8_t* data, std::size_t size, ControlMessage& out,
                   std::string& error) {
    if (size < kControlFixed || get_u32(data) != kControlMagic) {
        error = "not a control message";
        return false;
    }
    if (get_u16(data + 4) != kProtocolVersion) {
        error = "unsupported control protocol version";
        return false;
    }
    const std::uint8_t type = data[6];
    if (type < 1 || type > 5) {
        error = "unknown control message type " + std::to_string(type);
        return false;
    }
    out.type = static_cast<ControlType>(type);
    out.session = get_u64(data + 8);
    out.seq = get_u32(data + 16);
    out.t0 = static_cast<std::int64_t>(get_u64(data + 20));
    out.t1 = static_cast<std::int64_t>(get_u64(data + 28));
    out.t2 = static_cast<std::int64_t>(get_u64(data + 36));
    out.frames = get_u32(data + 44);
    out.json.assign(reinterpret_cast<const char*>(data + kControlFixed), size - kControlFixed);
    if (out.type != ControlType::kHello && out.type != ControlType::kStart && !out.json.empty()) {
        error = "unexpected trailing bytes in a control message";
        return false;
    }
    return true;
}

}  // namespace rgbd::sensors::net
