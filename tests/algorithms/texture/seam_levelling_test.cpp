// Seam levelling and the photo-consistency check of the texture (issue 36), on a flat square of
// 20 x 20 cells at 1 m in front of identical cameras (known answers): two charts of flat colours
// 100 and 140 meet at x = 0; without levelling the texture steps by 40 levels there, with it the
// step is a fraction of that and the far corners keep their colours. A camera whose image shows
// an occluder (red) or a highlight (+100 levels) over part of the square loses exactly those
// faces, even when it is the best-placed camera, and the selection then avoids it there.
#include "algorithms/texture/seam_levelling.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "algorithms/render/rasterizer.hpp"
#include "algorithms/texture/atlas.hpp"
#include "algorithms/texture/photo_consistency.hpp"

namespace {

using namespace rgbd;

constexpr int kCells = 20;
constexpr double kHalf = 0.2;  // the square spans [-0.2, 0.2] m in x and y, at z = 1 m

struct Square {
    std::vector<Eigen::Vector3d> vertices;
    std::vector<std::array<int, 3>> triangles;
    Square() {
        for (int j = 0; j <= kCells; ++j)
            for (int i = 0; i <= kCells; ++i)
                vertices.emplace_back(-kHalf + 2 * kHalf * i / kCells,
                                      -kHalf + 2 * kHalf * j / kCells, 1.0);
        auto id = [](int i, int j) { return j * (kCells + 1) + i; };
        for (int j = 0; j < kCells; ++j)
            for (int i = 0; i < kCells; ++i) {  // wound to face the camera at the origin
                triangles.push_back({id(i, j), id(i, j + 1), id(i + 1, j)});
                triangles.push_back({id(i + 1, j), id(i, j + 1), id(i + 1, j + 1)});
            }
    }
    Eigen::Vector3d centre(std::size_t f) const {
        const auto& t = triangles[f];
        return (vertices[t[0]] + vertices[t[1]] + vertices[t[2]]) / 3.0;
    }
};

/// A camera at the origin looking along +z, its image one flat grey.
texture::TextureView flat_view(int grey, const std::string& name) {
    texture::TextureView v;
    v.intrinsics = {.width = 320, .height = 240, .fx = 300, .fy = 300, .cx = 159.5, .cy = 119.5};
    v.image = cv::Mat(240, 320, CV_8UC3, cv::Scalar(grey, grey, grey));
    v.name = name;
    return v;
}

/// The grey level of the texture at face f's centre (the mean of its corners' coordinates).
double texture_grey(const TexturedMesh& m, std::size_t f) {
    Eigen::Vector2f uv = Eigen::Vector2f::Zero();
    for (const int k : m.face_uvs[f]) uv += m.uvs[k] / 3.0f;
    const cv::Mat& a = m.atlases[m.face_atlas[f]];
    const cv::Vec3b c =
        a.at<cv::Vec3b>(static_cast<int>(uv.y() * a.rows), static_cast<int>(uv.x() * a.cols));
    return (c[0] + c[1] + c[2]) / 3.0;
}

/// Mean texture grey of the faces whose centre's x lies in [x0, x1].
double mean_grey(const TexturedMesh& m, const Square& s, double x0, double x1) {
    double sum = 0;
    int n = 0;
    for (std::size_t f = 0; f < s.triangles.size(); ++f) {
        const double x = s.centre(f).x();
        if (x < x0 || x > x1) continue;
        sum += texture_grey(m, f);
        ++n;
    }
    EXPECT_GT(n, 0);
    return sum / n;
}

TEST(SeamLevelling, AStepBetweenTwoFlatChartsIsLevelledLocally) {
    const Square s;
    const render::RenderScene scene(s.vertices, s.triangles);
    const std::vector<texture::TextureView> views = {flat_view(100, "dark"),
                                                     flat_view(140, "bright")};
    std::vector<int> label(s.triangles.size());
    for (std::size_t f = 0; f < label.size(); ++f) label[f] = s.centre(f).x() < 0 ? 0 : 1;
    const auto adjacency = texture::face_adjacency(s.triangles);
    const auto charts = texture::make_charts(label, adjacency);
    ASSERT_EQ(charts.size(), 2u);
    const std::vector<texture::ColourGain> gains(2);
    const std::vector<Rgb> flat(s.triangles.size(), Rgb{128, 128, 128});
    Report levelling, atlas_plain, atlas_levelled;
    const texture::SeamCorrections seams = texture::level_seams(
        scene, views, gains, charts, adjacency, texture::LevellingOptions{}, levelling);
    EXPECT_EQ(levelling["seam_edges"].get<int>(), kCells);
    const TexturedMesh plain = texture::build_atlas(scene, views, charts, gains, flat,
                                                    texture::AtlasOptions{}, atlas_plain);
    const TexturedMesh levelled = texture::build_atlas(
        scene, views, charts, gains, flat, texture::AtlasOptions{}, atlas_levelled, &seams);
    const double cell = 2 * kHalf / kCells;
    // The faces next to the seam on either side.
    const double step_plain = mean_grey(plain, s, 0, cell) - mean_grey(plain, s, -cell, 0);
    const double step_levelled = mean_grey(levelled, s, 0, cell) - mean_grey(levelled, s, -cell, 0);
    EXPECT_NEAR(step_plain, 40.0, 1.0);
    EXPECT_LT(std::abs(step_levelled), 10.0) << "plain step " << step_plain;
    // At the seam's vertices, the corrected colours of the two charts.
    double seam_step = 0;
    int seam_vertices = 0;
    for (std::size_t v = 0; v < s.vertices.size(); ++v) {
        if (std::abs(s.vertices[v].x()) > 1e-9) continue;
        const auto& dark = seams.chart_vertex[charts[0].view == 0 ? 0 : 1];
        const auto& bright = seams.chart_vertex[charts[0].view == 0 ? 1 : 0];
        seam_step +=
            (140.0 + bright.at(static_cast<int>(v))[1]) - (100.0 + dark.at(static_cast<int>(v))[1]);
        ++seam_vertices;
    }
    ASSERT_EQ(seam_vertices, kCells + 1);
    seam_step /= seam_vertices;
    EXPECT_LT(std::abs(seam_step), 3.0);
    std::printf(
        "step across the seam: %.2f levels without levelling, %.2f with (texels next "
        "to it), %.2f at its vertices\n",
        step_plain, step_levelled, seam_step);
    EXPECT_GT(step_levelled, -1.0);  // levelled towards each other, not past
    // Local: ten cells from the seam the colours are the images' own.
    EXPECT_NEAR(mean_grey(levelled, s, -kHalf, -kHalf + 2 * cell), 100.0, 2.0);
    EXPECT_NEAR(mean_grey(levelled, s, kHalf - 2 * cell, kHalf), 140.0, 2.0);
    // Symmetric: both charts move by the same amount.
    const double dark_shift = mean_grey(levelled, s, -cell, 0) - 100.0;
    const double bright_shift = 140.0 - mean_grey(levelled, s, 0, cell);
    EXPECT_NEAR(dark_shift, bright_shift, 1.5);
    EXPECT_GT(dark_shift, 10.0);
}

TEST(PhotoConsistency, AnOccluderAndAHighlightAreRejectedAndAvoided) {
    const Square s;
    const render::RenderScene scene(s.vertices, s.triangles);
    std::vector<texture::TextureView> views;
    for (int v = 0; v < 5; ++v) views.push_back(flat_view(120, "camera " + std::to_string(v)));
    // Camera 2 sees a red occluder over x < -0.05 m; camera 4 a highlight over y > 0.05 m.
    // Pixels: x = -0.05 m at 1 m is column 159.5 - 15 = 144.5; y = 0.05 m is row 134.5.
    views[2].image(cv::Rect(0, 0, 145, 240)).setTo(cv::Scalar(0, 0, 255));
    views[4].image(cv::Rect(0, 135, 320, 105)).setTo(cv::Scalar(220, 220, 220));
    texture::FaceQuality quality;
    quality.views = 5;
    quality.faces = static_cast<int>(s.triangles.size());
    quality.quality.assign(5 * s.triangles.size(), 1.0f);
    for (std::size_t f = 0; f < s.triangles.size(); ++f) {  // 2 and 4 the best-placed cameras
        quality.quality[2 * s.triangles.size() + f] = 2.0f;
        quality.quality[4 * s.triangles.size() + f] = 1.5f;
    }
    const std::vector<texture::ColourGain> gains(5);
    Report report;
    const std::size_t rejected = texture::reject_inconsistent_views(
        scene, views, gains, texture::ConsistencyOptions{}, quality, report);
    std::size_t occluded = 0, highlighted = 0;
    for (int f = 0; f < quality.faces; ++f) {
        const Eigen::Vector3d c = s.centre(f);
        // Whole faces (all four samples) inside the occluder / highlight, or clearly outside.
        const double margin = 2 * kHalf / kCells;
        for (const int v : {0, 1, 3}) EXPECT_GT(quality.at(v, f), 0.0f) << f;
        if (c.x() < -0.05 - margin) {
            EXPECT_EQ(quality.at(2, f), 0.0f) << f;
            ++occluded;
        } else if (c.x() > -0.05 + margin) {
            EXPECT_EQ(quality.at(2, f), 2.0f) << f;
        }
        if (c.y() > 0.05 + margin) {
            EXPECT_EQ(quality.at(4, f), 0.0f) << f;
            ++highlighted;
        } else if (c.y() < 0.05 - margin) {
            EXPECT_EQ(quality.at(4, f), 1.5f) << f;
        }
    }
    EXPECT_GT(occluded, 100u);
    EXPECT_GT(highlighted, 100u);
    EXPECT_GE(rejected, occluded + highlighted);
    EXPECT_LE(rejected, occluded + highlighted + 4 * kCells * 2);  // the faces on the borders
    // The selection takes the best remaining camera: never 2 under the occluder.
    texture::SelectionOptions options;
    options.sweeps = 0;
    const auto selection =
        texture::select_views(quality, texture::face_adjacency(s.triangles), options);
    for (int f = 0; f < quality.faces; ++f) {
        if (s.centre(f).x() < -0.05 - 2 * kHalf / kCells)
            EXPECT_NE(selection.label[f], 2) << f;
        else if (s.centre(f).x() > -0.05 + 2 * kHalf / kCells)
            EXPECT_EQ(selection.label[f], 2) << f;
    }
    // Off: nothing rejected.
    texture::ConsistencyOptions off;
    off.enabled = false;
    Report off_report;
    EXPECT_EQ(texture::reject_inconsistent_views(scene, views, gains, off, quality, off_report),
              0u);
}

}  // namespace
