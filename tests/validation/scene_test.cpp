// Scene elements of synthetic captures (validation/synth/scene.hpp): segment images whose labels
// agree with the geometry (subject pixels on the sphere, support pixels on the floor, background
// pixels on a wall, box, cylinder or person of gt/scene.json), the bare scene unchanged, the
// plinth, deterministic placement, and refused values.
#include "validation/synth/scene.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "synth_test_shapes.hpp"
#include "toolkit/error.hpp"
#include "validation/synth/synthesize.hpp"

namespace rgbd::synth {
namespace {

namespace fs = std::filesystem;

constexpr double kSphereRadius = 0.225;  // icosphere of radius 1 placed 0.45 m high (default)

Mesh sphere() {
    Mesh mesh;
    testing::add_icosphere(mesh, Eigen::Vector3d::Zero(), 1.0, 4);
    return mesh;
}

nlohmann::json read_json(const fs::path& p) {
    std::ifstream in(p);
    return nlohmann::json::parse(in);
}

Pose pose_from_json(const nlohmann::json& m) {
    Pose p = Pose::Identity();
    Eigen::Matrix4d a = Eigen::Matrix4d::Zero();
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) a(r, c) = m[r][c].get<double>();
    p.matrix() = a;
    return p;
}

Eigen::Vector3d vec(const nlohmann::json& j) {
    return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()};
}

/// Distance of p from the surface of a background element of gt/scene.json (walls: the plane
/// within its extent; boxes and people: outside distance to the box, 0 inside; cylinders alike).
double distance_to_element(const nlohmann::json& e, const Eigen::Vector3d& p) {
    const std::string kind = e["kind"];
    if (kind == "wall") {
        const Eigen::Vector3d foot = vec(e["bottom_centre"]), n = vec(e["normal"]);
        const double h = p.z() - foot.z();
        const double out_of_height = std::max({0.0, -h, h - e["height_m"].get<double>()});
        return std::hypot(std::abs(n.dot(p - foot)), out_of_height);
    }
    const Eigen::Vector3d bottom = vec(e["bottom_centre"]);
    if (kind == "cylinder") {
        const double radial =
            std::max(0.0, (p - bottom).head<2>().norm() - e["radius_m"].get<double>());
        const double h = p.z() - bottom.z();
        return std::hypot(radial, std::max({0.0, -h, h - e["height_m"].get<double>()}));
    }
    const Eigen::Vector3d size = vec(e["size_m"]);
    const double yaw = e["yaw_deg"].get<double>() * M_PI / 180.0;
    const Eigen::Vector3d d = p - bottom;
    const Eigen::Vector3d local(std::cos(yaw) * d.x() + std::sin(yaw) * d.y(),
                                -std::sin(yaw) * d.x() + std::cos(yaw) * d.y(), d.z());
    const Eigen::Vector3d lo(-size.x() / 2, -size.y() / 2, 0),
        hi(size.x() / 2, size.y() / 2, size.z());
    return (lo - local).cwiseMax(local - hi).cwiseMax(0.0).norm();
}

class SceneCapture : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() /
               ("rgbd_scene_test_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }

    static SynthOptions small() {
        SynthOptions o;
        o.sensors = 3;
        o.resolution_scale = 0.25;
        o.frames = 2;
        return o;
    }

    fs::path dir_;
};

TEST_F(SceneCapture, SegmentLabelsAgreeWithTheGeometry) {
    SynthOptions o = small();
    o.scene = scene_preset("room");
    o.scene.walls = 3;
    const SynthSummary summary = synthesize_capture(sphere(), dir_, o);
    ASSERT_EQ(summary.views, 6);
    const SyntheticRig rig = make_rig(o);
    const auto poses = read_json(dir_ / "gt/world_from_depth.json");
    const auto scene = read_json(dir_ / "gt/scene.json")["scene"];
    const double floor_z = scene["floor_z"].get<double>();
    const double lowest = rig.object_centre.z() - kSphereRadius;
    EXPECT_NEAR(floor_z, lowest, 1e-9);
    int walls = 0, clutter = 0, people = 0;
    for (const auto& e : scene["elements"]) {
        walls += e["kind"] == "wall";
        clutter += e["kind"] == "box" || e["kind"] == "cylinder";
        people += e["kind"] == "person";
        if (e["kind"] == "box" || e["kind"] == "cylinder" || e["kind"] == "person") {
            EXPECT_NEAR(e["bottom_centre"][2].get<double>(), floor_z, 1e-12);
            const Eigen::Vector2d c(e["bottom_centre"][0].get<double>(),
                                    e["bottom_centre"][1].get<double>());
            for (const auto& s : rig.sensors)  // no sensor inside an element
                EXPECT_GT((c - s.true_world_from_depth[0].translation().head<2>()).norm(), 0.25);
            if (e["kind"] != "person") {
                EXPECT_GE(c.norm(), 0.6 * 1.5 - 1e-9);
                EXPECT_LE(c.norm(), 1.3 * 1.5 + 1e-9);
            }
        }
    }
    EXPECT_EQ(walls, 3);
    EXPECT_EQ(clutter, 4);
    EXPECT_EQ(people, 1);

    long counts[5] = {0, 0, 0, 0, 0};
    long checked_subject = 0, checked_support = 0, checked_background = 0;
    for (const auto& s : rig.sensors) {
        const Pose world_from_depth = pose_from_json(poses[s.spec.id]);
        for (int f = 0; f < o.frames; ++f) {
            char name[32];
            std::snprintf(name, sizeof name, "%06d.png", f);
            const fs::path seg_path = dir_ / "gt" / s.spec.id / "segment" / name;
            ASSERT_TRUE(fs::exists(seg_path)) << seg_path;
            const cv::Mat seg = cv::imread(seg_path.string(), cv::IMREAD_UNCHANGED);
            const cv::Mat depth =
                cv::imread((dir_ / s.spec.id / "depth" / name).string(), cv::IMREAD_UNCHANGED);
            const cv::Mat clean = cv::imread(
                (dir_ / "gt" / s.spec.id / "depth_clean" / name).string(), cv::IMREAD_UNCHANGED);
            ASSERT_EQ(seg.type(), CV_8UC1);
            ASSERT_EQ(seg.size(), depth.size());
            ASSERT_EQ(seg.cols, s.spec.depth.width);
            for (int r = 0; r < seg.rows; ++r)
                for (int c = 0; c < seg.cols; ++c) {
                    const int label = seg.at<std::uint8_t>(r, c);
                    ASSERT_LE(label, 4);
                    ++counts[label];
                    // 0 exactly where the noisy depth is invalid.
                    EXPECT_EQ(label == 0, depth.at<std::uint16_t>(r, c) == 0);
                    const std::uint16_t z = clean.at<std::uint16_t>(r, c);
                    if (label == 0 || label == 4 || z == 0) continue;
                    const Eigen::Vector3d p =
                        world_from_depth * s.spec.depth.unproject(c, r, z / s.spec.depth_scale);
                    if (label == 1) {
                        ++checked_subject;
                        EXPECT_NEAR((p - rig.object_centre).norm(), kSphereRadius, 0.003);
                    } else if (label == 2) {
                        ++checked_support;
                        EXPECT_NEAR(p.z(), floor_z, 0.01);
                    } else {
                        ++checked_background;
                        double best = 1e9;
                        for (const auto& e : scene["elements"])
                            if (e["label"] == 3) best = std::min(best, distance_to_element(e, p));
                        EXPECT_LT(best, 0.01) << p.transpose();
                    }
                }
        }
    }
    EXPECT_GT(checked_subject, 1000);
    EXPECT_GT(checked_support, 1000);
    EXPECT_GT(checked_background, 1000);
    EXPECT_GT(counts[1] + counts[2] + counts[3],
              0.8 * (counts[0] + counts[1] + counts[2] + counts[3] + counts[4]));
}

TEST_F(SceneCapture, BareSceneHasNoSupportOrBackgroundAndDefaultsAreUnchanged) {
    SynthOptions o = small();
    o.scene = scene_preset("bare");
    synthesize_capture(sphere(), dir_, o);
    EXPECT_FALSE(read_json(dir_ / "gt/scene.json").contains("scene"));
    const SyntheticRig rig = make_rig(o);
    PlacedMesh placed = place_mesh(sphere(), o.height_m, o.up, rig.object_centre);
    const RenderScene scene = make_render_scene(placed, o, rig);
    EXPECT_EQ(placed.surroundings.object_triangles, -1);
    // The render scene is the subject alone, as before scene elements existed.
    const RenderScene subject(placed.mesh);
    EXPECT_EQ(scene.triangles(), subject.triangles());
    for (const auto& s : rig.sensors) {
        const cv::Mat seg = cv::imread((dir_ / "gt" / s.spec.id / "segment/000001.png").string(),
                                       cv::IMREAD_UNCHANGED);
        ASSERT_FALSE(seg.empty());
        EXPECT_EQ(cv::countNonZero(seg == 2) + cv::countNonZero(seg == 3), 0);
        EXPECT_GT(cv::countNonZero(seg == 1), 500);
        EXPECT_EQ(cv::countNonZero(seg > 4), 0);
    }
}

TEST_F(SceneCapture, TheSubjectRendersAlikeWithAndWithoutAFarScene) {
    // Walls behind the subject and nothing else: without noise, the subject's pixels and depths
    // are the same; the walls only add pixels.
    SynthOptions o = small();
    o.frames = 1;
    o.noise = NoiseOptions::none();
    const SyntheticRig rig = make_rig(o);
    PlacedMesh bare_placed = place_mesh(sphere(), o.height_m, o.up, rig.object_centre);
    const RenderScene bare = make_render_scene(bare_placed, o, rig);
    SynthOptions w = o;
    w.scene.walls = 4;
    PlacedMesh wall_placed = place_mesh(sphere(), o.height_m, o.up, rig.object_centre);
    const RenderScene walled = make_render_scene(wall_placed, w, rig);
    const auto& s = rig.sensors[1];
    const RenderedView a =
        render_view(bare, bare_placed, s.spec, s.traits, s.true_world_from_depth[0], o, 7);
    const RenderedView b =
        render_view(walled, wall_placed, s.spec, s.traits, s.true_world_from_depth[0], w, 7);
    long subject = 0;
    for (int r = 0; r < a.segment.rows; ++r)
        for (int c = 0; c < a.segment.cols; ++c) {
            const bool in_a = a.segment.at<std::uint8_t>(r, c) == 1;
            ASSERT_EQ(in_a, b.segment.at<std::uint8_t>(r, c) == 1) << r << " " << c;
            if (!in_a) continue;
            ++subject;
            ASSERT_EQ(a.noisy.depth.at<float>(r, c), b.noisy.depth.at<float>(r, c));
        }
    EXPECT_GT(subject, 300);
    EXPECT_EQ(cv::countNonZero(a.segment == 3), 0);
    EXPECT_GT(cv::countNonZero(b.segment == 3), 1000);
}

TEST(SceneElements, PlinthUnderTheSubjectAndTheFloorBelowIt) {
    SceneOptions o;
    o.floor = true;
    o.plinth_height_m = 0.3;
    SceneFrame f;
    f.subject_lo = Eigen::Vector3d(-0.1, -0.2, 1.0);
    f.subject_hi = Eigen::Vector3d(0.1, 0.2, 1.5);
    f.sensor_positions = {{1.5, 0, 1.6}, {-1.5, 0, 1.6}};
    SceneSoup soup;
    soup.vertices = {{0, 0, 1}, {0.1, 0, 1}, {0, 0.1, 1}};
    soup.triangles = {{0, 1, 2}};
    Surroundings s;
    s.object_triangles = 1;
    add_surroundings(soup, s, o, f);
    EXPECT_NEAR(s.floor_z, 0.7, 1e-12);
    ASSERT_EQ(s.elements.size(), 2u);
    const SceneElement& plinth = s.elements[0];
    EXPECT_EQ(plinth.kind, ElementKind::kPlinth);
    EXPECT_EQ(plinth.label, SegmentLabel::kSupport);
    EXPECT_NEAR(plinth.geometry["size_m"][0].get<double>(), 0.48, 1e-12);  // 1.2 x 0.4
    EXPECT_NEAR(plinth.geometry["size_m"][2].get<double>(), 0.3, 1e-12);
    double top = -1e9;
    for (int t = plinth.first_triangle; t < plinth.end_triangle; ++t)
        for (int k = 0; k < 3; ++k) top = std::max(top, soup.vertices[soup.triangles[t][k]].z());
    EXPECT_NEAR(top, 1.0, 1e-12);
    EXPECT_EQ(s.label_of(0), SegmentLabel::kSubject);
    EXPECT_EQ(s.label_of(plinth.first_triangle), SegmentLabel::kSupport);
    EXPECT_EQ(s.label_of(s.elements[1].end_triangle - 1), SegmentLabel::kSupport);
    EXPECT_EQ(s.elements[1].kind, ElementKind::kFloor);
    // A plinth wider than the ring would enclose the sensors.
    f.subject_lo.head<2>() = Eigen::Vector2d(-2, -2);
    f.subject_hi.head<2>() = Eigen::Vector2d(2, 2);
    Surroundings t;
    EXPECT_NO_THROW(add_surroundings(soup, t, o, f));  // the sensors look down from above it
    f.sensor_positions = {{1.5, 0, 0.9}};
    Surroundings u;
    EXPECT_THROW(add_surroundings(soup, u, o, f), InputError);
}

TEST(SceneElements, PlacementFollowsTheSeed) {
    SynthOptions o;
    o.sensors = 4;
    o.scene = scene_preset("room");
    const SyntheticRig rig = make_rig(o);
    const auto layout = [&](std::uint64_t seed) {
        o.seed = seed;
        PlacedMesh placed = place_mesh(sphere(), o.height_m, o.up, rig.object_centre);
        make_render_scene(placed, o, rig);
        return placed.surroundings.to_json().dump();
    };
    EXPECT_EQ(layout(3), layout(3));
    EXPECT_NE(layout(3), layout(4));
}

TEST(SceneElements, RejectsBadValuesNamingTheField) {
    const auto message = [](const SceneOptions& o) {
        try {
            o.check();
        } catch (const InputError& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    SceneOptions o;
    o.walls = 7;
    EXPECT_NE(message(o).find("walls"), std::string::npos);
    o = SceneOptions{};
    o.plinth_height_m = -1;
    EXPECT_NE(message(o).find("plinth_height_m"), std::string::npos);
    o.plinth_height_m = std::nan("");
    EXPECT_NE(message(o).find("plinth_height_m"), std::string::npos);
    o = SceneOptions{};
    o.clutter = -2;
    EXPECT_NE(message(o).find("clutter"), std::string::npos);
    EXPECT_THROW(scene_preset("garden"), InputError);
    // Scene elements need the ring and a static subject.
    SynthOptions s;
    s.scene.floor = true;
    EXPECT_NO_THROW(s.check());
    s.rig = RigKind::kTurntable;
    EXPECT_THROW(s.check(), InputError);
    s.rig = RigKind::kRing;
    s.motion = MotionKind::kTurn;
    EXPECT_THROW(s.check(), InputError);
}

}  // namespace
}  // namespace rgbd::synth
