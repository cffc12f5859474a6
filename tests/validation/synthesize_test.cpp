// Virtual rigs, placement, texture and views of the synthetic harness (in memory).
#include "validation/synth/synthesize.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstring>

#include "synth_test_shapes.hpp"
#include "toolkit/error.hpp"

namespace rgbd::synth {
namespace {

TEST(SynthRig, RingPosesCalibrationErrorAndClocks) {
    SynthOptions o;
    const SyntheticRig rig = make_rig(o);
    ASSERT_EQ(rig.sensors.size(), 8u);
    const double centre_z = 1.6 - 1.5 * std::tan(10.0 * M_PI / 180.0);
    EXPECT_NEAR(rig.object_centre.z(), centre_z, 1e-12);
    for (std::size_t i = 0; i < rig.sensors.size(); ++i) {
        const auto& s = rig.sensors[i];
        const Pose& truth = s.true_world_from_depth.at(0);
        EXPECT_EQ(s.spec.id, "k2-" + std::to_string(i));
        EXPECT_NEAR(truth.translation().head<2>().norm(), 1.5, 1e-12);
        EXPECT_NEAR(truth.translation().z(), 1.6, 1e-12);
        // The optical axis passes through the object centre, 10 degrees down.
        const Eigen::Vector3d to_centre = (rig.object_centre - truth.translation()).normalized();
        EXPECT_NEAR(to_centre.dot(truth.linear().col(2)), 1.0, 1e-12);
        EXPECT_NEAR(std::asin(-truth.linear().col(2).z()) * 180 / M_PI, 10.0, 1e-9);
        if (i == 0) {
            EXPECT_LT(rotation_error_deg(s.spec.world_from_depth, truth), 1e-9);
            EXPECT_LT(translation_error_m(s.spec.world_from_depth, truth), 1e-12);
        } else {
            EXPECT_NEAR(rotation_error_deg(s.spec.world_from_depth, truth), 1.5, 1e-6);
            EXPECT_NEAR(translation_error_m(s.spec.world_from_depth, truth), 0.015, 1e-12);
        }
        EXPECT_LE(std::llabs(s.spec.clock_offset_ns), 500'000'000LL);
    }
    EXPECT_NE(rig.sensors[1].spec.clock_offset_ns, rig.sensors[2].spec.clock_offset_ns);
    // Neighbours 45 degrees apart.
    const Eigen::Vector3d a = rig.sensors[0].true_world_from_depth[0].translation();
    const Eigen::Vector3d b = rig.sensors[1].true_world_from_depth[0].translation();
    EXPECT_NEAR(std::acos(a.head<2>().normalized().dot(b.head<2>().normalized())) * 180 / M_PI,
                45.0, 1e-9);
    // Another seed, another error direction, same magnitude.
    o.seed = 2;
    o.calib_error_deg = 0.7;
    o.calib_error_mm = 4.0;
    const SyntheticRig other = make_rig(o);
    EXPECT_NEAR(rotation_error_deg(other.sensors[3].spec.world_from_depth,
                                   other.sensors[3].true_world_from_depth[0]),
                0.7, 1e-6);
    EXPECT_NEAR(translation_error_m(other.sensors[3].spec.world_from_depth,
                                    other.sensors[3].true_world_from_depth[0]),
                0.004, 1e-12);
}

TEST(SynthRig, TurntableNominalAndTruePoses) {
    SynthOptions o;
    o.rig = RigKind::kTurntable;
    const SyntheticRig rig = make_rig(o);
    ASSERT_EQ(rig.sensors.size(), 1u);
    const auto& s = rig.sensors[0];
    EXPECT_EQ(s.spec.model, "sr300");
    ASSERT_EQ(s.true_world_from_depth.size(), 12u);
    ASSERT_EQ(s.nominal_world_from_depth.size(), 12u);
    EXPECT_LT(rotation_error_deg(s.true_world_from_depth[0], s.nominal_world_from_depth[0]), 1e-9);
    EXPECT_NEAR((s.true_world_from_depth[0].translation() - rig.object_centre).head<2>().norm(),
                0.55, 1e-12);
    double max_err = 0;
    for (int k = 1; k < 12; ++k) {
        const double nominal_step =
            rotation_error_deg(s.nominal_world_from_depth[k], s.nominal_world_from_depth[k - 1]);
        EXPECT_NEAR(nominal_step, 30.0, 1e-6);
        const double true_step =
            rotation_error_deg(s.true_world_from_depth[k], s.true_world_from_depth[k - 1]);
        EXPECT_NEAR(true_step, 30.0, 1.5);
        max_err = std::max(
            max_err, rotation_error_deg(s.true_world_from_depth[k], s.nominal_world_from_depth[k]));
        EXPECT_GT(s.hub_time_ns[k], s.hub_time_ns[k - 1]);
    }
    EXPECT_GT(max_err, 0.5);  // the tilted axis shows
    EXPECT_LT(max_err, 4.0);
}

TEST(SynthPlace, ScalesToHeightAndCentres) {
    Mesh mesh;
    testing::add_quad(mesh, Eigen::Vector3d(3, 5, 7), Eigen::Vector3d::UnitX(),
                      Eigen::Vector3d::UnitY(), 2.0);  // 4 x 4 in x, y; flat in z
    const PlacedMesh placed = place_mesh(mesh, 0.6, UpAxis::kY, Eigen::Vector3d(0, 0, 1.3));
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9), hi = -lo;
    for (const auto v : placed.mesh.vertices()) {
        lo = lo.cwiseMin(to_eigen(placed.mesh.point(v)));
        hi = hi.cwiseMax(to_eigen(placed.mesh.point(v)));
    }
    EXPECT_NEAR(hi.z() - lo.z(), 0.6, 1e-12);  // input y became world z
    EXPECT_NEAR(hi.y() - lo.y(), 0.0, 1e-12);
    EXPECT_TRUE((0.5 * (lo + hi)).isApprox(Eigen::Vector3d(0, 0, 1.3), 1e-12));
    EXPECT_NEAR(placed.scale, 0.15, 1e-12);
    EXPECT_THROW(place_mesh(mesh, 0.6, UpAxis::kZ, Eigen::Vector3d::Zero()), InputError);
}

TEST(SynthTexture, SolidTextureVariesWithHeightAndChecker) {
    // Expected colours worked out by hand from the documented formula with the default options
    // (hue 360 z / 0.5 m, saturation 0.65, value 0.95, 3 cm cells, dark cells x 0.55) and
    // checked against Python's colorsys.hsv_to_rgb, rounded to 8 bits.
    // z = 1 cm: hue 7.2 deg, a bright cell (cells 0, 0, 0).
    EXPECT_EQ(texture_color({0.01, 0.01, 0.01}), (Rgb{242, 104, 85}));
    // One cell over in x: the same hue in a dark cell, value 0.95 x 0.55.
    EXPECT_EQ(texture_color({0.04, 0.01, 0.01}), (Rgb{133, 57, 47}));
    // z = 13 cm: hue 93.6 deg (green), a bright cell (cells 0, 0, 4).
    EXPECT_EQ(texture_color({0.01, 0.01, 0.13}), (Rgb{154, 242, 85}));
    // Non-default options: the hue offset turns the colour, a zero checker has no dark cells.
    TextureOptions t;
    t.hue_offset_deg = 120.0 - 7.2;  // hue 120 deg at z = 1 cm: pure green over grey
    t.checker_size_m = 0;
    EXPECT_EQ(texture_color({0.04, 0.01, 0.01}, t), (Rgb{85, 242, 85}));
    TextureOptions bad;
    bad.checker_dark = 2;
    EXPECT_THROW(bad.check(), InputError);
}

struct SphereView {
    SynthOptions options;
    SyntheticRig rig;
    PlacedMesh placed;
    RenderScene scene;
};

SphereView sphere_view(bool noise) {
    SynthOptions o;
    o.sensors = 2;
    if (!noise) o.noise = NoiseOptions::none();
    SyntheticRig rig = make_rig(o);
    Mesh mesh;
    testing::add_icosphere(mesh, Eigen::Vector3d::Zero(), 1.0, 5);
    PlacedMesh placed = place_mesh(mesh, 0.4, UpAxis::kZ, rig.object_centre);
    RenderScene scene(placed.mesh);
    return {o, std::move(rig), std::move(placed), std::move(scene)};
}

TEST(SynthView, ColourIsTheTextureSeenByTheColourCamera) {
    const SphereView v = sphere_view(false);
    const auto& s = v.rig.sensors[1];
    const Pose& world_from_depth = s.true_world_from_depth[0];
    const RenderedView view =
        render_view(v.scene, v.placed, s.spec, s.traits, world_from_depth, v.options, 5);
    const Pose color_from_world = s.spec.color_from_depth * world_from_depth.inverse();
    long checked = 0, good = 0;
    for (int r = 0; r < view.clean.depth.rows; ++r)
        for (int c = 0; c < view.clean.depth.cols; ++c) {
            const double z = view.clean.depth.at<double>(r, c);
            if (!std::isfinite(z)) continue;
            EXPECT_EQ(view.noisy.labels.at<std::uint8_t>(r, c), 1);
            EXPECT_NEAR(view.noisy.depth.at<float>(r, c), z, 1e-6);
            const Eigen::Vector3d p = world_from_depth * s.spec.depth.unproject(c, r, z);
            const Eigen::Vector2d uv = s.spec.color.project(color_from_world * p);
            const cv::Vec3b bgr = view.color.at<cv::Vec3b>(static_cast<int>(std::lround(uv.y())),
                                                           static_cast<int>(std::lround(uv.x())));
            const Rgb want = texture_color(v.placed.object_from_world(p), v.options.texture);
            ++checked;
            good += std::abs(bgr[2] - want.r) <= 4 && std::abs(bgr[1] - want.g) <= 4 &&
                    std::abs(bgr[0] - want.b) <= 4;
        }
    EXPECT_GT(checked, 5000);
    EXPECT_GT(good, 0.9 * checked);
}

TEST(SynthView, DeterministicForASeedAndAnyThreadCount) {
    const SphereView v = sphere_view(true);
    const auto& s = v.rig.sensors[0];
    RenderedView a;
    {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
        a = render_view(v.scene, v.placed, s.spec, s.traits, s.true_world_from_depth[0], v.options,
                        9);
    }
    const RenderedView b =
        render_view(v.scene, v.placed, s.spec, s.traits, s.true_world_from_depth[0], v.options, 9);
    EXPECT_EQ(std::memcmp(a.noisy.depth.data, b.noisy.depth.data, a.noisy.depth.total() * 4), 0);
    EXPECT_EQ(std::memcmp(a.noisy.labels.data, b.noisy.labels.data, a.noisy.labels.total()), 0);
    EXPECT_EQ(cv::norm(a.color, b.color, cv::NORM_INF), 0.0);
}

TEST(SynthOptionsCheck, RejectsAbsurdValues) {
    SynthOptions o;
    o.sensors = 0;
    EXPECT_THROW(o.check(), InputError);
    o = SynthOptions{};
    o.height_m = -1;
    EXPECT_THROW(o.check(), InputError);
    o = SynthOptions{};
    o.frames = 0;
    EXPECT_THROW(o.check(), InputError);
    EXPECT_THROW(parse_rig_kind("dome"), InputError);
    EXPECT_THROW(parse_up_axis("x"), InputError);
}

}  // namespace
}  // namespace rgbd::synth
