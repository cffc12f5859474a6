// The 3D video folder (io/video.hpp): Draco round trip within the position grid and the colour
// bits, metadata in every frame, a folder written as it goes and read back, a capture cut short
// (frames on disk that the index does not name yet), stale and corrupt frame files named.
#include "io/video.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <random>

#include "tests/support/temp_dir.hpp"
#include "toolkit/error.hpp"

namespace {

namespace fs = std::filesystem;
using rgbd::io::ColoredPoints;

ColoredPoints random_points(std::size_t n, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> pos(-0.3f, 0.3f);
    ColoredPoints p;
    for (std::size_t i = 0; i < n; ++i) {
        p.xyz.emplace_back(pos(rng), pos(rng), 1.0f + pos(rng));
        p.rgb.push_back(rgbd::Rgb{static_cast<std::uint8_t>(rng()),
                                  static_cast<std::uint8_t>(rng()),
                                  static_cast<std::uint8_t>(rng())});
    }
    return p;
}

/// For every decoded point, the input point it came from (Draco reorders): nearest by position.
double worst_match(const ColoredPoints& in, const ColoredPoints& out, int color_bits,
                   int& worst_color) {
    double worst = 0;
    worst_color = 0;
    for (std::size_t i = 0; i < out.size(); ++i) {
        std::size_t best = 0;
        float d = 1e9f;
        for (std::size_t j = 0; j < in.size(); ++j) {
            const float e = (in.xyz[j] - out.xyz[i]).squaredNorm();
            if (e < d) d = e, best = j;
        }
        worst = std::max(worst, static_cast<double>(std::sqrt(d)));
        const int keep = 8 - color_bits;
        const rgbd::Rgb a = in.rgb[best], b = out.rgb[i];
        for (auto [x, y] : {std::pair{a.r, b.r}, {a.g, b.g}, {a.b, b.b}})
            worst_color = std::max(worst_color, std::abs(int(x >> keep) - int(y >> keep)));
    }
    return worst;
}

fs::path scratch(const std::string& name) {
    return rgbd::test::fresh_temp_dir("video_test", name, false);
}

TEST(Video, DracoKeepsPointsOnTheGridAndColourBits) {
    const ColoredPoints in = random_points(3000, 1);
    rgbd::io::DracoSettings settings;
    settings.position_quantum_m = 0.001;
    for (int bits : {8, 6}) {
        settings.color_bits = bits;
        const auto bytes = rgbd::io::encode_draco(in, settings, {7, 42, 123456789, 555});
        rgbd::io::FrameMeta meta;
        const ColoredPoints out = rgbd::io::decode_draco(bytes.data(), bytes.size(), "mem", &meta);
        ASSERT_EQ(out.size(), in.size());
        int worst_color = 0;
        // Half a grid step per axis: sqrt(3) * 0.5 mm.
        EXPECT_LE(worst_match(in, out, bits, worst_color), 0.00087 + 1e-6);
        EXPECT_EQ(worst_color, 0) << bits << " bits";
        EXPECT_EQ(meta.frame, 7);
        EXPECT_EQ(meta.set, 42);
        EXPECT_EQ(meta.time_ns, 123456789);
        EXPECT_EQ(meta.spread_ns, 555);
        // Far smaller than 15 bytes per point (float x y z + r g b), even for random points.
        EXPECT_LT(bytes.size(), in.size() * 15 / 2);
    }
    // Garbage is an InputError naming what was read.
    const std::vector<std::uint8_t> junk(100, 7);
    try {
        rgbd::io::decode_draco(junk.data(), junk.size(), "junk.drc");
        FAIL() << "no error";
    } catch (const rgbd::InputError& e) {
        EXPECT_NE(std::string(e.what()).find("junk.drc"), std::string::npos);
    }
}

TEST(Video, FolderWrittenAsItGoesIsReadBackAndProblemsAreNamed) {
    const fs::path dir = scratch("folder");
    rgbd::io::Rig rig;
    rig.sensors.resize(1);
    rig.sensors[0].id = "k2-0";
    rig.sensors[0].depth = {512, 424, 365.5, 365.5, 256, 212};
    rig.sensors[0].color = {512, 424, 365.5, 365.5, 256, 212};
    {
        rgbd::io::VideoWriter writer(dir, rig, 30.0, {}, {{"placement", "hub"}}, 1000.0);
        for (int k = 0; k < 4; ++k) {
            rgbd::io::VideoFrame info;
            info.set = 10 + k;
            info.time_ns = 1'000'000'000 + k * 33'333'333;
            info.sensors = 1;
            const auto& written = writer.add(random_points(500 + 100 * k, k), info);
            EXPECT_EQ(written.file, rgbd::io::video_frame_file(k));
            writer.update_last(5.0, 50.0 + k);
            if (k == 1) writer.write_index();  // frames 2 and 3: on disk, not in the index
        }
        // Cut short here: no finish().
    }
    rgbd::io::VideoInfo video = rgbd::io::read_video(dir);
    EXPECT_FALSE(video.complete);
    EXPECT_EQ(video.frame_rate_hz, 30.0);
    EXPECT_EQ(video.header["placement"], "hub");
    ASSERT_EQ(video.frames.size(), 4u);
    for (int k = 0; k < 4; ++k) {
        const auto& f = video.frames[static_cast<std::size_t>(k)];
        EXPECT_EQ(f.frame, k);
        EXPECT_EQ(f.indexed, k < 2);
        EXPECT_EQ(f.set, 10 + k) << "from the frame's own metadata when not indexed";
        EXPECT_EQ(f.points, static_cast<std::size_t>(500 + 100 * k));
        EXPECT_TRUE(f.problem.empty()) << f.problem;
    }
    EXPECT_EQ(rgbd::io::read_video_frame(video, 3).size(), 800u);

    // A stale file (replaced by another frame's bytes) and a corrupt one are named.
    fs::copy_file(dir / "frames/000000.drc", dir / "frames/000001.drc",
                  fs::copy_options::overwrite_existing);
    {
        std::fstream f(dir / "frames/000000.drc", std::ios::in | std::ios::out | std::ios::binary);
        f.write("XXXXX", 5);
    }
    video = rgbd::io::read_video(dir);
    EXPECT_NE(video.frames[0].problem.find("not a Draco file"), std::string::npos);
    EXPECT_NE(video.frames[1].problem.find("stale or truncated"), std::string::npos);
    EXPECT_THROW(rgbd::io::read_video_frame(video, 0), rgbd::InputError);
    EXPECT_THROW(rgbd::io::read_video_frame(video, 9), rgbd::InputError);

    // Not a video.
    EXPECT_THROW(rgbd::io::read_video(dir / "frames"), rgbd::InputError);
    // A writer refuses a non-empty folder.
    EXPECT_THROW(rgbd::io::VideoWriter(dir, rig, 30.0, {}, {}), rgbd::IoError);
    fs::remove_all(dir);
}

}  // namespace
