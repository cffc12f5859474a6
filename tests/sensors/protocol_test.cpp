// Tests of the capture network's wire format (sensors/network/protocol.hpp): round trips,
// and every kind of malformed message (truncated, padded, flipped bits, garbage) rejected
// with a reason instead of crashing.
#include "sensors/network/protocol.hpp"

#include <gtest/gtest.h>

#include <random>

#include "sensors/network/transport.hpp"
#include "toolkit/error.hpp"

namespace rgbd::sensors::net {
namespace {

std::vector<std::uint8_t> sample_frame(FrameHeader& h) {
    h.session = 0x1234567890abcdefULL;
    h.sensor_id = "k2-3";
    h.index = 41;
    h.device_ns = -5;
    h.node_ns = 1'700'000'000'123'456'789LL;
    h.sent_ns = 1'700'000'000'150'000'000LL;  // the node's send time (issue 38)
    h.width = 512;
    h.height = 424;
    const std::vector<std::uint8_t> depth = {1, 2, 3, 4, 5, 6, 7, 8};
    const std::vector<std::uint8_t> color = {0xff, 0xd8, 9, 9, 9};
    std::vector<std::uint8_t> out;
    encode_frame(h, depth.data(), depth.size(), color.data(), color.size(), out);
    return out;
}

TEST(Protocol, FrameRoundTrip) {
    FrameHeader h;
    const auto bytes = sample_frame(h);
    FrameView v;
    std::string error;
    ASSERT_TRUE(parse_frame(bytes.data(), bytes.size(), v, error)) << error;
    EXPECT_EQ(v.header.session, h.session);
    EXPECT_EQ(v.header.sensor_id, "k2-3");
    EXPECT_EQ(v.header.index, 41);
    EXPECT_EQ(v.header.device_ns, -5);
    EXPECT_EQ(v.header.node_ns, h.node_ns);
    EXPECT_EQ(v.header.sent_ns, h.sent_ns);
    EXPECT_EQ(v.header.width, 512);
    EXPECT_EQ(v.header.height, 424);
    ASSERT_EQ(v.header.depth_bytes, 8u);
    ASSERT_EQ(v.header.color_bytes, 5u);
    EXPECT_EQ(v.depth[7], 8);
    EXPECT_EQ(v.color[1], 0xd8);
}

TEST(Protocol, TruncatedPaddedAndFlippedFramesAreRejected) {
    FrameHeader h;
    const auto bytes = sample_frame(h);
    FrameView v;
    std::string error;
    for (std::size_t cut = 0; cut < bytes.size(); ++cut)
        EXPECT_FALSE(parse_frame(bytes.data(), cut, v, error)) << "cut " << cut;
    auto padded = bytes;
    padded.push_back(0);
    EXPECT_FALSE(parse_frame(padded.data(), padded.size(), v, error));
    EXPECT_NE(error.find("truncated or padded"), std::string::npos);
    for (std::size_t i = 0; i < bytes.size(); ++i)
        for (int bit = 0; bit < 8; ++bit) {
            auto bad = bytes;
            bad[i] ^= static_cast<std::uint8_t>(1u << bit);
            EXPECT_FALSE(parse_frame(bad.data(), bad.size(), v, error))
                << "byte " << i << " bit " << bit;
        }
}

TEST(Protocol, GarbageIsRejected) {
    std::mt19937 rng(5);
    FrameView v;
    ControlMessage c;
    std::string error;
    for (int trial = 0; trial < 2000; ++trial) {
        std::vector<std::uint8_t> junk(rng() % 400);
        for (auto& b : junk) b = static_cast<std::uint8_t>(rng());
        EXPECT_FALSE(parse_frame(junk.data(), junk.size(), v, error));
        EXPECT_FALSE(parse_control(junk.data(), junk.size(), c, error));
    }
    // Garbage behind a valid magic.
    for (int trial = 0; trial < 2000; ++trial) {
        std::vector<std::uint8_t> junk(kFrameHeaderSize + rng() % 400);
        for (auto& b : junk) b = static_cast<std::uint8_t>(rng());
        junk[0] = 0x52, junk[1] = 0x47, junk[2] = 0x44, junk[3] = 0x46;
        EXPECT_FALSE(parse_frame(junk.data(), junk.size(), v, error));
    }
}

TEST(Protocol, ControlRoundTripAndRejects) {
    ControlMessage m;
    m.type = ControlType::kProbeReply;
    m.seq = 77;
    m.t0 = 1;
    m.t1 = -2;
    m.t2 = 3'000'000'000'000LL;
    auto bytes = encode_control(m);
    ControlMessage back;
    std::string error;
    ASSERT_TRUE(parse_control(bytes.data(), bytes.size(), back, error)) << error;
    EXPECT_EQ(back.type, ControlType::kProbeReply);
    EXPECT_EQ(back.seq, 77u);
    EXPECT_EQ(back.t1, -2);
    EXPECT_EQ(back.t2, m.t2);
    ControlMessage hello;
    hello.type = ControlType::kHello;
    hello.session = 9;
    hello.json = R"({"sensor":"a"})";
    bytes = encode_control(hello);
    ASSERT_TRUE(parse_control(bytes.data(), bytes.size(), back, error));
    EXPECT_EQ(back.json, hello.json);
    for (std::size_t cut = 0; cut < 48; ++cut)
        EXPECT_FALSE(parse_control(bytes.data(), cut, back, error));
    bytes = encode_control(m);
    bytes[6] = 99;  // unknown type
    EXPECT_FALSE(parse_control(bytes.data(), bytes.size(), back, error));
    bytes = encode_control(m);
    bytes.push_back(1);  // trailing bytes on a probe reply
    EXPECT_FALSE(parse_control(bytes.data(), bytes.size(), back, error));
}

TEST(Transport, ControlEndpoint) {
    EXPECT_EQ(control_endpoint_for("tcp://*:5555"), "tcp://*:5556");
    EXPECT_EQ(control_endpoint_for("tcp://10.0.0.2:7000"), "tcp://10.0.0.2:7001");
    EXPECT_THROW(control_endpoint_for("tcp://host"), InputError);
    EXPECT_THROW(control_endpoint_for("tcp://host:x1"), InputError);
    EXPECT_THROW(control_endpoint_for("tcp://host:65535"), InputError);
}

}  // namespace
}  // namespace rgbd::sensors::net
