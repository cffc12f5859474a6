// Colour pose refinement (algorithms/texture/colour_pose_refinement.hpp) on a bumpy sphere with a
// smooth non-periodic solid texture seen by eight cameras, three of whose poses are off by
// 1 degree and 5 mm (a depth-to-colour extrinsic error): the refinement recovers the true poses,
// leaves the exact ones in place, lowers the photometric residual and raises the textured
// model's PSNR against the true images; corrections beyond the limits are refused.
#include "algorithms/texture/colour_pose_refinement.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "algorithms/render/rasterizer.hpp"
#include "algorithms/texture/surface_colour.hpp"
#include "algorithms/texture/texture_mesh.hpp"
#include "tests/algorithms/texture/uv_sphere.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;

namespace {

/// Smooth, non-periodic solid texture (sums of sines of incommensurate frequencies, 3-15 cm).
Rgb pattern(const Eigen::Vector3d& p) {
    const double a = std::sin(41 * p.x() + 7 * p.y()) * std::cos(37 * p.y() - 23 * p.z());
    const double b = std::sin(97 * p.z() + 53 * p.x() + 1.0) * std::sin(71 * p.y() + 0.5);
    const double c = std::sin(151 * p.x() - 131 * p.z()) + std::sin(263 * p.y() + 197 * p.z());
    const auto level = [](double v) {
        return static_cast<std::uint8_t>(std::clamp(v, 0.0, 255.0));
    };
    return {level(128 + 60 * a + 30 * b + 20 * c), level(128 + 50 * b - 40 * a),
            level(110 + 40 * c + 30 * a)};
}

/// A bumpy sphere of radius about r at the origin.
Mesh blob(double r, int rings, int segments) {
    // Bumps (up to 25% of the radius) break the sphere's symmetry: a common rotation of all
    // cameras about its centre would leave a sphere's colours consistent.
    return test::uv_sphere(rings, segments, [r](double th, double ph) {
        return r * (1 + 0.15 * std::sin(2 * th) * std::cos(3 * ph + 0.4) +
                    0.1 * std::cos(3 * th) * std::sin(2 * ph));
    });
}

/// Eight cameras on a ring at 0.7 m, alternately 0.2 m above and below, looking at the centre.
std::vector<texture::TextureView> ring_views(const render::RenderScene& scene) {
    const PinholeIntrinsics k{
        .width = 640, .height = 480, .fx = 700, .fy = 700, .cx = 319.5, .cy = 239.5};
    std::vector<texture::TextureView> views;
    for (int i = 0; i < 8; ++i) {
        const double a = 2 * M_PI * i / 8;
        texture::TextureView v;
        v.intrinsics = k;
        v.world_from_camera =
            look_at(Eigen::Vector3d(0.7 * std::cos(a), 0.7 * std::sin(a), i % 2 ? 0.2 : -0.2),
                    Eigen::Vector3d::Zero());
        v.image = render::render_color(
            scene, k, v.world_from_camera, [](const Eigen::Vector3d& p, int) { return pattern(p); },
            Rgb{0, 0, 0});
        v.name = "camera " + std::to_string(i);
        views.push_back(std::move(v));
    }
    return views;
}

/// The colour camera's pose with an extrinsic error: `deg` about `axis`, `mm` along `dir`.
Pose perturbed(const Pose& world_from_camera, double deg, const Eigen::Vector3d& axis, double mm,
               const Eigen::Vector3d& dir) {
    Pose error = Pose::Identity();
    error.linear() = Eigen::AngleAxisd(deg * M_PI / 180, axis.normalized()).matrix();
    error.translation() = 0.001 * mm * dir.normalized();
    return world_from_camera * error;
}

struct Scene : ::testing::Test {
    static void SetUpTestSuite() {
        mesh_ = new Mesh(blob(0.15, 48, 96));
        scene_ = new render::RenderScene(*mesh_);
        truth_ = new std::vector<texture::TextureView>(ring_views(*scene_));
        off_ = new std::vector<texture::TextureView>(*truth_);
        auto& off = *off_;
        off[1].world_from_camera =
            perturbed(off[1].world_from_camera, 1.0, {0, 1, 0.3}, 5.0, {1, 0, 0});
        off[4].world_from_camera =
            perturbed(off[4].world_from_camera, 1.0, {1, -0.2, 0}, 5.0, {0, 1, 1});
        off[6].world_from_camera =
            perturbed(off[6].world_from_camera, 1.0, {0.3, 0.5, 1}, 5.0, {-1, 0.5, 0});
    }
    static void TearDownTestSuite() {
        delete mesh_;
        delete scene_;
        delete truth_;
        delete off_;
    }
    static Mesh* mesh_;
    static render::RenderScene* scene_;
    static std::vector<texture::TextureView>* truth_;
    static std::vector<texture::TextureView>* off_;
};
Mesh* Scene::mesh_ = nullptr;
render::RenderScene* Scene::scene_ = nullptr;
std::vector<texture::TextureView>* Scene::truth_ = nullptr;
std::vector<texture::TextureView>* Scene::off_ = nullptr;

}  // namespace

TEST_F(Scene, RecoversThePerturbedPosesAndKeepsTheExactOnes) {
    texture::RefineOptions options;
    options.enabled = true;
    Report report;
    const std::vector<Pose> poses = texture::refine_colour_poses(*scene_, *off_, options, report);
    ASSERT_EQ(poses.size(), truth_->size());
    for (std::size_t c = 0; c < poses.size(); ++c) {
        const Pose& truth = (*truth_)[c].world_from_camera;
        const double before_deg = rotation_error_deg((*off_)[c].world_from_camera, truth);
        const double deg = rotation_error_deg(poses[c], truth);
        const double mm = 1000 * translation_error_m(poses[c], truth);
        SCOPED_TRACE("camera " + std::to_string(c) + ": " + report["cameras"][c].dump() +
                     report["iterations"].dump());
        EXPECT_LT(deg, 0.3);
        EXPECT_LT(mm, 2.0);
        if (before_deg > 0.5) {
            EXPECT_EQ(report["cameras"][c]["status"], "refined");
            EXPECT_NEAR(report["cameras"][c]["rotation_deg"].get<double>(), 1.0, 0.3);
        }
    }
    EXPECT_LT(report["residual_after"].get<double>(),
              0.6 * report["residual_before"].get<double>());
    EXPECT_EQ(report["refused"].get<int>(), 0);
}

TEST_F(Scene, TexturingWithRefinementRaisesThePsnrAgainstTheTrueImages) {
    texture::TextureOptions options;
    Report plain_report, refined_report;
    const TexturedMesh plain = texture::texture_mesh(*mesh_, *off_, options, plain_report);
    options.refine.enabled = true;
    const TexturedMesh refined = texture::texture_mesh(*mesh_, *off_, options, refined_report);
    options.refine.enabled = false;
    Report truth_report;
    const TexturedMesh exact = texture::texture_mesh(*mesh_, *truth_, options, truth_report);
    const double psnr_off = texture::surface_colour_error(plain, *truth_).psnr_db;
    const double psnr_refined = texture::surface_colour_error(refined, *truth_).psnr_db;
    const double psnr_exact = texture::surface_colour_error(exact, *truth_).psnr_db;
    EXPECT_TRUE(refined_report.contains("refine"));
    EXPECT_FALSE(plain_report.contains("refine"));
    EXPECT_GT(psnr_refined, psnr_off + 2.0) << psnr_off << " -> " << psnr_refined;
    // Near the exact poses' PSNR (about 50 dB here, where a twentieth of a pixel shows).
    EXPECT_GT(psnr_refined, psnr_exact - 2.0)
        << psnr_off << " -> " << psnr_refined << " (exact " << psnr_exact << ")";
}

TEST_F(Scene, CorrectionsBeyondTheLimitsAreRefused) {
    texture::RefineOptions options;
    options.enabled = true;
    options.max_rotation_deg = 0.3;  // below the 1-degree errors
    Report report;
    const std::vector<Pose> poses = texture::refine_colour_poses(*scene_, *off_, options, report);
    for (const int c : {1, 4, 6}) {
        EXPECT_EQ(report["cameras"][c]["status"], "refused");
        EXPECT_NE(report["cameras"][c]["reason"].get<std::string>().find("exceeds"),
                  std::string::npos);
        EXPECT_TRUE(poses[c].isApprox((*off_)[c].world_from_camera, 1e-12));
    }
    EXPECT_GE(report["refused"].get<int>(), 3);
}

TEST(ColourPoseRefinement, RejectsBadOptionsAndImages) {
    texture::RefineOptions options;
    options.iterations = 0;
    EXPECT_THROW(options.check(), InputError);
    options = {};
    options.max_rotation_deg = std::nan("");
    EXPECT_THROW(options.check(), InputError);
    options = {};
    options.levels = 9;
    EXPECT_THROW(options.check(), InputError);
    const Mesh mesh = blob(0.15, 8, 16);
    const render::RenderScene scene(mesh);
    texture::TextureView v;
    v.intrinsics = {.width = 64, .height = 48, .fx = 70, .fy = 70, .cx = 31.5, .cy = 23.5};
    v.image = cv::Mat(10, 10, CV_8UC3);
    v.name = "small";
    Report report;
    EXPECT_THROW(texture::refine_colour_poses(scene, {v}, texture::RefineOptions{}, report),
                 InputError);
}
