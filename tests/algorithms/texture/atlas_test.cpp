// Flat cells of the texture atlas (issue 36): faces no camera sees get flat colours, quantised
// to at most AtlasOptions::max_flat_cells cells (the finest power-of-two step per channel that
// fits), each cell the mean colour of its faces, so every face keeps its colour to within the
// step; without a limit every distinct colour keeps its own exact cell.
#include "algorithms/texture/atlas.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <set>

#include "algorithms/render/rasterizer.hpp"

namespace {

using namespace rgbd;

/// A strip of 3000 triangles, triangle f coloured (16 (f mod 16), 16 (f / 16 mod 16), f / 256):
/// 3000 distinct colours.
struct Strip {
    std::vector<Eigen::Vector3d> vertices;
    std::vector<std::array<int, 3>> triangles;
    std::vector<Rgb> colours;
    Strip() {
        const int n = 3000;
        for (int i = 0; i <= n / 2; ++i) {
            vertices.emplace_back(0.01 * i, 0.0, 1.0);
            vertices.emplace_back(0.01 * i, 0.01, 1.0);
        }
        for (int i = 0; i < n / 2; ++i) {
            triangles.push_back({2 * i, 2 * i + 2, 2 * i + 1});
            triangles.push_back({2 * i + 1, 2 * i + 2, 2 * i + 3});
        }
        for (int f = 0; f < n; ++f)
            colours.push_back({static_cast<std::uint8_t>(16 * (f % 16)),
                               static_cast<std::uint8_t>(16 * ((f / 16) % 16)),
                               static_cast<std::uint8_t>(f / 256)});
    }
};

/// The atlas colour at face f's texture coordinate (all three corners share it).
Rgb colour_of(const TexturedMesh& m, std::size_t f) {
    const Eigen::Vector2f uv = m.uvs[m.face_uvs[f][0]];
    const cv::Mat& a = m.atlases[m.face_atlas[f]];
    const cv::Vec3b c =
        a.at<cv::Vec3b>(static_cast<int>(uv.y() * a.rows), static_cast<int>(uv.x() * a.cols));
    return {c[2], c[1], c[0]};
}

TEST(Atlas, FlatCellsAreQuantisedToTheLimitAndKeepTheColourWithinTheStep) {
    const Strip strip;
    const render::RenderScene scene(strip.vertices, strip.triangles);
    texture::AtlasOptions options;
    options.max_flat_cells = 64;
    Report report;
    const TexturedMesh m = texture::build_atlas(scene, {}, {}, {}, strip.colours, options, report);
    ASSERT_TRUE(m.has_texture());
    const int quantum = report["flat_colour_quantum"].get<int>();
    EXPECT_LE(report["flat_cells"].get<int>(), 64);
    EXPECT_GT(quantum, 1);
    EXPECT_EQ(report["flat_faces"].get<int>(), 3000);
    for (std::size_t f = 0; f < strip.colours.size(); ++f) {
        const Rgb got = colour_of(m, f), want = strip.colours[f];
        ASSERT_LT(std::abs(got.r - want.r), quantum) << f;
        ASSERT_LT(std::abs(got.g - want.g), quantum) << f;
        ASSERT_LT(std::abs(got.b - want.b), quantum) << f;
    }
    // The cells take a small part of the atlas: 64 cells of 4 x 4 texels fit into 64 x 64.
    EXPECT_LE(m.atlases[0].total(), 64u * 64u);
}

TEST(Atlas, WithoutALimitEveryColourKeepsAnExactCell) {
    const Strip strip;
    const render::RenderScene scene(strip.vertices, strip.triangles);
    texture::AtlasOptions options;
    options.max_flat_cells = 1 << 20;
    Report report;
    const TexturedMesh m = texture::build_atlas(scene, {}, {}, {}, strip.colours, options, report);
    EXPECT_EQ(report["flat_colour_quantum"].get<int>(), 1);
    EXPECT_EQ(report["flat_cells"].get<int>(), 3000);
    for (std::size_t f = 0; f < strip.colours.size(); ++f) {
        const Rgb got = colour_of(m, f), want = strip.colours[f];
        ASSERT_TRUE(got.r == want.r && got.g == want.g && got.b == want.b) << f;
    }
}

TEST(Atlas, MaxFlatCellsIsChecked) {
    texture::AtlasOptions options;
    options.max_flat_cells = 0;
    EXPECT_THROW(options.check(), InputError);
}

}  // namespace
