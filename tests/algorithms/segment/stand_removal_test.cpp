// Stand removal (algorithms/segment/stand_removal): a known platter plane under a known object,
// seen by cameras around it; the plane found, the platter gone, the object kept; no plane, no
// removal.
#include "algorithms/segment/stand_removal.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "toolkit/error.hpp"
#include "toolkit/pose.hpp"
#include "toolkit/types.hpp"

using namespace rgbd;

namespace {

constexpr double kPi = std::numbers::pi;

/// Camera pose looking horizontally-ish at the origin from azimuth `az` (image -y = world up
/// tilted by the 10 deg down-look).
Pose camera_at(double az) {
    const Eigen::Vector3d pos(0.55 * std::cos(az), 0.55 * std::sin(az), 0.1);
    return look_at(pos, Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ());
}

struct Scene {
    std::vector<PointCloud> views;
    std::size_t platter = 0, object = 0;
};

/// 8 world-frame views: an ellipsoid (object, its lowest point at height 0) and, with
/// `platter`, a disc of radius 0.12 m in the plane through the origin with normal `n`; 0.3 mm
/// noise along z. Object points carry red = 200, platter points red = 10.
Scene make_scene(bool platter, const Eigen::Vector3d& n = Eigen::Vector3d::UnitZ()) {
    Scene s;
    std::mt19937 rng(3);
    std::normal_distribution<double> noise(0.0, 0.0003);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const Eigen::Vector3d nn = n.normalized();
    const Eigen::Vector3d e1 = nn.unitOrthogonal(), e2 = nn.cross(e1);
    for (int v = 0; v < 8; ++v) {
        PointCloud view;
        view.view.id = v;
        view.view.sensor = "sr300-0";
        view.view.frame = ViewFrame::kWorld;
        view.view.world_from_sensor = camera_at(2 * kPi * v / 8);
        auto colors = view.add_colors();
        for (int i = 0; i < 4000; ++i) {  // object: ellipsoid centred 0.1 m above the origin
            const double th = std::acos(1 - 2 * u(rng)), ph = 2 * kPi * u(rng);
            const Eigen::Vector3d p(0.05 * std::sin(th) * std::cos(ph),
                                    0.04 * std::sin(th) * std::sin(ph),
                                    0.1 + 0.1 * std::cos(th) + noise(rng));
            colors.set(*view.points.insert(to_point(p)), {200, 0, 0});
            ++s.object;
        }
        if (platter) {
            for (int i = 0; i < 3000; ++i) {
                const double r = 0.12 * std::sqrt(u(rng)), ph = 2 * kPi * u(rng);
                const Eigen::Vector3d p =
                    r * (std::cos(ph) * e1 + std::sin(ph) * e2) + noise(rng) * nn;
                colors.set(*view.points.insert(to_point(p)), {10, 0, 0});
                ++s.platter;
            }
        }
        s.views.push_back(std::move(view));
    }
    return s;
}

}  // namespace

TEST(StandRemoval, CamerasUpIsTheWorldUpAroundATurntable) {
    const Scene s = make_scene(false);
    const auto up = segment::cameras_up(s.views);
    ASSERT_TRUE(up.has_value());
    EXPECT_GT(up->dot(Eigen::Vector3d::UnitZ()), std::cos(0.5 * kPi / 180));
}

TEST(StandRemoval, FindsATiltedPlatterAndRemovesIt) {
    // The platter's normal 3 deg off the cameras' up (a turntable axis known only roughly).
    const Eigen::Vector3d n(std::sin(3 * kPi / 180), 0, std::cos(3 * kPi / 180));
    Scene s = make_scene(true, n);
    const auto plane = segment::find_support_plane(s.views, Eigen::Vector3d::UnitZ());
    ASSERT_TRUE(plane.has_value());
    EXPECT_GT(plane->normal.dot(n), std::cos(0.3 * kPi / 180));
    EXPECT_NEAR(plane->offset, 0.0, 0.0005);

    const Report r = segment::remove_stand(s.views);
    ASSERT_TRUE(r["found"].get<bool>()) << r.dump();
    std::size_t platter_left = 0, object_left = 0;
    for (const auto& v : s.views) {
        const auto c = v.colors();
        for (auto i : v.points) (c.r[i] == 10 ? platter_left : object_left) += 1;
    }
    EXPECT_EQ(platter_left, 0u);
    // The ellipsoid loses only its cap within the margin (2.5 mm of 200 mm height: ~1.3%, the
    // tilted plane cuts a little more on one side).
    EXPECT_GT(object_left, std::size_t(0.96 * s.object));
    EXPECT_EQ(r["removed"].get<std::size_t>(), s.platter + s.object - object_left);
}

TEST(StandRemoval, NoPlatterNoRemoval) {
    Scene s = make_scene(false);
    const Report r = segment::remove_stand(s.views);
    EXPECT_FALSE(r["found"].get<bool>()) << r.dump();
    EXPECT_EQ(r["removed"].get<std::size_t>(), 0u);
    std::size_t left = 0;
    for (const auto& v : s.views) left += v.size();
    EXPECT_EQ(left, s.object);
}

TEST(StandRemoval, ViewsWithoutPosesAreLeftAlone) {
    Scene s = make_scene(true);
    for (auto& v : s.views) v.view.world_from_sensor.reset();
    const Report r = segment::remove_stand(s.views);
    EXPECT_FALSE(r["found"].get<bool>());
    EXPECT_TRUE(r.contains("note"));
}

TEST(StandRemoval, RejectsBadOptions) {
    segment::StandOptions o;
    o.max_tilt_deg = 95;
    EXPECT_THROW(o.check(), InputError);
    o = {};
    o.inlier_m = 0;
    EXPECT_THROW(o.check(), InputError);
}
