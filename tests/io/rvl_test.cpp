// Tests of the RVL depth codec (io/rvl.hpp): exact round trips on edge-case and Kinect-like
// images, the compression ratio on Kinect v2 like depth, and corrupt input (truncated,
// trailing bytes, garbage) raising InputError instead of crashing or over-running.
#include "io/rvl.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "toolkit/error.hpp"

namespace rgbd::io {
namespace {

std::vector<std::uint16_t> round_trip(const std::vector<std::uint16_t>& depth,
                                      std::size_t* bytes = nullptr) {
    std::vector<std::uint8_t> packed;
    const std::size_t size = rvl_compress(depth.data(), depth.size(), packed);
    EXPECT_EQ(size, packed.size());
    EXPECT_EQ(size % 4, 0u);
    EXPECT_LE(size, rvl_max_compressed_size(depth.size()));
    if (bytes) *bytes = size;
    std::vector<std::uint16_t> back(depth.size(), 7);
    rvl_decompress(packed.data(), packed.size(), back.data(), back.size());
    return back;
}

// A Kinect v2 like depth image (512x424, mm): a wall at about 3 m, a sphere ("head") at
// 1.5 m, Kinect v2 axial noise, 1 mm quantisation, dropouts in short runs and at
// the silhouette (where Kinect v2 loses flying pixels), a few random outliers.
std::vector<std::uint16_t> kinect_like_depth(unsigned seed) {
    const int w = 512, h = 424;
    const double f = 365.5, cx = 256, cy = 212;
    std::mt19937 rng(seed);
    std::normal_distribution<double> gauss(0.0, 1.0);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    std::vector<std::uint16_t> d(static_cast<std::size_t>(w) * h, 0);
    const double sx = 0.0, sy = 0.0, sz = 1.5, r = 0.2;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const double rx = (x - cx) / f, ry = (y - cy) / f;
            double z = 3.0 + 0.3 * rx - 0.2 * ry;  // tilted wall
            bool edge = false;
            // ray-sphere intersection along (rx, ry, 1)
            const double a = rx * rx + ry * ry + 1, b = -2 * (rx * sx + ry * sy + sz),
                         c = sx * sx + sy * sy + sz * sz - r * r;
            const double disc = b * b - 4 * a * c;
            if (disc >= 0) {
                z = (-b - std::sqrt(disc)) / (2 * a);
                edge = disc < 0.02 * b * b;
            }
            // Kinect v2 axial noise, head-on (docs/algorithms.md §4 (noise models)): 1.4 mm at 1.5
            // m, 2.7 at 3 m.
            const double sigma_m = 1e-3 * (1.5 - 0.5 * z + 0.3 * z * z);
            double v = z + sigma_m * gauss(rng);
            if (uni(rng) < 0.005) v = 0.5 + 4.0 * uni(rng);  // outlier
            if (edge && uni(rng) < 0.5) v = 0;               // silhouette dropout
            d[static_cast<std::size_t>(y) * w + x] =
                static_cast<std::uint16_t>(std::lround(std::max(0.0, v) * 1000.0));
        }
    // dropout runs (multipath, dark material)
    for (int k = 0; k < 300; ++k) {
        const std::size_t start = static_cast<std::size_t>(uni(rng) * (d.size() - 40));
        const std::size_t len = 1 + static_cast<std::size_t>(uni(rng) * 30);
        for (std::size_t i = 0; i < len; ++i) d[start + i] = 0;
    }
    return d;
}

TEST(Rvl, RoundTripsEdgeCases) {
    EXPECT_EQ(round_trip({}), std::vector<std::uint16_t>{});
    const std::vector<std::vector<std::uint16_t>> cases = {
        {0},
        {1},
        {65535},
        {0, 0, 0, 0},
        {65535, 1, 65535, 1, 0, 65535},
        {1, 2, 3, 0, 0, 4, 5, 0},
        std::vector<std::uint16_t>(100000, 0),
        std::vector<std::uint16_t>(100000, 1234),
    };
    for (const auto& c : cases) EXPECT_EQ(round_trip(c), c);
}

TEST(Rvl, RoundTripsRandomAndWorstCaseImages) {
    std::mt19937 rng(3);
    std::uniform_int_distribution<int> value(0, 65535);
    std::vector<std::uint16_t> noise(512 * 424);
    for (auto& v : noise) v = static_cast<std::uint16_t>(value(rng));
    EXPECT_EQ(round_trip(noise), noise);
    std::vector<std::uint16_t> alternating(512 * 424);
    for (std::size_t i = 0; i < alternating.size(); ++i)
        alternating[i] = i % 2 ? 0 : (i % 4 ? 65535 : 1);
    EXPECT_EQ(round_trip(alternating), alternating);
    std::vector<std::uint16_t> swing(512 * 424);
    for (std::size_t i = 0; i < swing.size(); ++i) swing[i] = i % 2 ? 65535 : 1;
    EXPECT_EQ(round_trip(swing), swing);
}

TEST(Rvl, KinectLikeDepthCompressesAtLeast2point5) {
    for (unsigned seed = 1; seed <= 3; ++seed) {
        const auto depth = kinect_like_depth(seed);
        std::size_t bytes = 0;
        EXPECT_EQ(round_trip(depth, &bytes), depth);
        const double ratio = static_cast<double>(depth.size() * 2) / static_cast<double>(bytes);
        EXPECT_GE(ratio, 2.5) << "seed " << seed;
        RecordProperty("ratio_seed_" + std::to_string(seed), std::to_string(ratio));
    }
}

TEST(Rvl, ReusesTheOutputBuffer) {
    const auto depth = kinect_like_depth(5);
    std::vector<std::uint8_t> packed;
    rvl_compress(depth.data(), depth.size(), packed);
    const std::uint8_t* buffer = packed.data();
    for (int i = 0; i < 3; ++i) {
        rvl_compress(depth.data(), depth.size(), packed);
        EXPECT_EQ(packed.data(), buffer);  // no reallocation between frames
    }
}

TEST(Rvl, TruncatedInputThrows) {
    const auto depth = kinect_like_depth(7);
    std::vector<std::uint8_t> packed;
    rvl_compress(depth.data(), depth.size(), packed);
    std::vector<std::uint16_t> out(depth.size());
    for (std::size_t cut : {std::size_t{0}, std::size_t{1}, std::size_t{4}, packed.size() / 2,
                            packed.size() - 4, packed.size() - 1}) {
        EXPECT_THROW(rvl_decompress(packed.data(), cut, out.data(), out.size()), InputError)
            << "cut at " << cut;
    }
    // Too many pixels expected for the data: truncated as well.
    std::vector<std::uint16_t> bigger(depth.size() + 1);
    EXPECT_THROW(rvl_decompress(packed.data(), packed.size(), bigger.data(), bigger.size()),
                 InputError);
}

TEST(Rvl, TrailingBytesAndFewerPixelsThrow) {
    const std::vector<std::uint16_t> depth = {5, 6, 7, 0, 0, 9};
    std::vector<std::uint8_t> packed;
    rvl_compress(depth.data(), depth.size(), packed);
    std::vector<std::uint16_t> out(depth.size());
    auto longer = packed;
    longer.insert(longer.end(), {0, 0, 0, 0});
    EXPECT_THROW(rvl_decompress(longer.data(), longer.size(), out.data(), out.size()), InputError);
    EXPECT_THROW(rvl_decompress(packed.data(), packed.size(), out.data(), out.size() - 2),
                 InputError);
}

TEST(Rvl, GarbageNeverOverrunsAndMostlyThrows) {
    std::mt19937 rng(11);
    std::uniform_int_distribution<int> byte(0, 255);
    const std::size_t pixels = 512 * 424;
    // A guard region after the output catches any write past `pixels`.
    std::vector<std::uint16_t> out(pixels + 64, 0xBEEF);
    int thrown = 0;
    for (int trial = 0; trial < 200; ++trial) {
        std::vector<std::uint8_t> junk(4 * (1 + rng() % 4096));
        for (auto& b : junk) b = static_cast<std::uint8_t>(byte(rng));
        try {
            rvl_decompress(junk.data(), junk.size(), out.data(), pixels, "junk");
        } catch (const InputError& e) {
            ++thrown;
            EXPECT_NE(std::string(e.what()).find("junk: corrupt RVL depth"), std::string::npos);
        }
        for (std::size_t i = pixels; i < out.size(); ++i) ASSERT_EQ(out[i], 0xBEEF);
    }
    EXPECT_EQ(thrown, 200);
    // Bit flips in a valid stream: either an error or some image, never a crash.
    const auto depth = kinect_like_depth(9);
    std::vector<std::uint8_t> packed;
    rvl_compress(depth.data(), depth.size(), packed);
    for (int trial = 0; trial < 200; ++trial) {
        auto bad = packed;
        bad[rng() % bad.size()] ^= static_cast<std::uint8_t>(1u << (rng() % 8));
        try {
            rvl_decompress(bad.data(), bad.size(), out.data(), pixels);
        } catch (const InputError&) {
        }
        for (std::size_t i = pixels; i < out.size(); ++i) ASSERT_EQ(out[i], 0xBEEF);
    }
}

}  // namespace
}  // namespace rgbd::io
