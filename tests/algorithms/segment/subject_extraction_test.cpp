// Object extraction over the views of a ring (algorithms/segment/subject_extraction): a seated
// figure on a chair standing on a floor, a wall, a box of clutter and a second person outside
// the ring, seen by six cameras with 2 mm depth noise and a calibration error. Known answer per
// point (the red channel carries the label): the kept points must be the subject's.
#include "algorithms/segment/subject_extraction.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <random>

#include "toolkit/error.hpp"
#include "toolkit/pose.hpp"
#include "toolkit/types.hpp"

using namespace rgbd;

namespace {

constexpr double kPi = std::numbers::pi;
enum Label : std::uint8_t { kSubject = 1, kGround = 2, kBackground = 3 };

/// An axis-aligned box or a sphere of the scene, with its label.
struct Shape {
    bool sphere = false;
    Eigen::Vector3d lo, hi;  ///< box corners; sphere: lo = centre, hi.x() = radius
    Label label;
};

/// Distance along the unit ray (o, d) to the shape, or +inf.
double hit(const Shape& s, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
    constexpr double kInf = std::numeric_limits<double>::infinity();
    if (s.sphere) {
        const Eigen::Vector3d oc = o - s.lo;
        const double b = oc.dot(d), c = oc.squaredNorm() - s.hi.x() * s.hi.x();
        const double disc = b * b - c;
        if (disc < 0) return kInf;
        const double t = -b - std::sqrt(disc);
        return t > 0 ? t : kInf;
    }
    double t0 = 0, t1 = kInf;
    for (int a = 0; a < 3; ++a) {
        if (std::abs(d[a]) < 1e-12) {
            if (o[a] < s.lo[a] || o[a] > s.hi[a]) return kInf;
            continue;
        }
        double ta = (s.lo[a] - o[a]) / d[a], tb = (s.hi[a] - o[a]) / d[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta), t1 = std::min(t1, tb);
        if (t0 > t1) return kInf;
    }
    return t0 > 0 ? t0 : kInf;
}

/// A seated figure: head, torso and thighs on a chair whose four legs and the figure's shins
/// stand on the floor at z = 0.
void add_seated_figure(std::vector<Shape>& out) {
    out.push_back({true, {0, 0, 1.25}, {0.11, 0, 0}, kSubject});                 // head
    out.push_back({false, {-0.18, -0.12, 0.55}, {0.18, 0.12, 1.12}, kSubject});  // torso
    out.push_back({false, {-0.2, -0.2, 0.45}, {0.2, 0.2, 0.5}, kSubject});       // seat
    out.push_back({false, {-0.17, 0.15, 0.5}, {0.17, 0.45, 0.62}, kSubject});    // thighs
    out.push_back({false, {-0.15, 0.4, 0.0}, {0.15, 0.5, 0.55}, kSubject});      // shins
    for (double x : {-0.18, 0.16})
        for (double y : {-0.18, 0.16})
            out.push_back({false, {x, y, 0.0}, {x + 0.03, y + 0.03, 0.45}, kSubject});  // legs
}

struct Scene {
    std::vector<PointCloud> views;
};

/// Six depth cameras (256 x 212 pixels, 70 deg wide) on a 1.5 m ring at 1.6 m looking at
/// (0, 0, 0.8), ray casting the scene: a 6 m floor at z = 0 (a 2 cm slab), the seated figure,
/// a wall at x = 3 m, a box of clutter and a second person outside the ring. 2 mm noise along
/// each ray; rig poses off by `calib_deg` / `calib_mm` (view 0 exact); red = label. With
/// `look_away`, view 5 looks away from the figure at the wall; with `ball`, a ball on nothing
/// replaces the figure and the floor; with `wall_x`, the wall's face is at that x instead.
Scene make_scene(double calib_deg = 1.0, double calib_mm = 10.0, bool subject = true,
                 bool clutter = true, bool look_away = false, bool ball = false,
                 double wall_x = 3.0) {
    std::vector<Shape> shapes;
    if (ball)  // a ball 0.6 m across standing on nothing (no floor)
        shapes.push_back({true, {0, 0, 0.8}, {0.3, 0, 0}, kSubject});
    else if (subject)
        add_seated_figure(shapes);
    if (!ball) shapes.push_back({false, {-3, -3, -0.02}, {3, 3, 0.0}, kGround});
    if (clutter) {
        shapes.push_back({false, {wall_x, -3, 0.0}, {wall_x + 0.02, 3, 2.5}, kBackground});
        shapes.push_back({false, {1.1, 0.5, 0.0}, {1.4, 0.8, 0.4}, kBackground});    // clutter
        shapes.push_back({false, {-2.4, 0.9, 0.0}, {-2.0, 1.2, 1.7}, kBackground});  // person
    }
    Scene scene;
    std::mt19937 rng(7);
    std::normal_distribution<double> noise(0.0, 0.002);
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    PinholeIntrinsics intr;
    intr.width = 256, intr.height = 212, intr.fx = intr.fy = 182.75, intr.cx = 128, intr.cy = 106;
    for (int v = 0; v < 6; ++v) {
        const double az = 2 * kPi * v / 6 + 0.3;
        const Eigen::Vector3d pos(1.5 * std::cos(az), 1.5 * std::sin(az), 1.6);
        const Eigen::Vector3d target =
            look_away && v == 5 ? Eigen::Vector3d(3.0, pos.y(), 1.2) : Eigen::Vector3d(0, 0, 0.8);
        const Pose truth = look_at(pos, target, Eigen::Vector3d::UnitZ());
        Pose error = Pose::Identity();
        if (v > 0) {
            const Eigen::Vector3d axis(unit(rng), unit(rng), unit(rng));
            error.linear() = Eigen::AngleAxisd(calib_deg * kPi / 180, axis.normalized()).matrix();
            error.translation() =
                calib_mm / 1000.0 * Eigen::Vector3d(unit(rng), unit(rng), unit(rng)).normalized();
        }
        PointCloud view;
        view.view.id = v;
        view.view.sensor = "k2-" + std::to_string(v);
        view.view.intrinsics = intr;
        view.view.grid_width = intr.width;
        view.view.grid_height = intr.height;
        view.view.world_from_sensor = error * truth;
        auto colors = view.add_colors();
        auto pixels = view.add_pixel_map();
        for (int r = 0; r < intr.height; ++r)
            for (int c = 0; c < intr.width; ++c) {
                const Eigen::Vector3d ray_s =
                    Eigen::Vector3d((c - intr.cx) / intr.fx, (r - intr.cy) / intr.fy, 1.0);
                const Eigen::Vector3d d = (truth.linear() * ray_s).normalized();
                double best = std::numeric_limits<double>::infinity();
                Label label = kGround;
                for (const Shape& s : shapes) {
                    const double t = hit(s, pos, d);
                    if (t < best) best = t, label = s.label;
                }
                const double z = best / ray_s.norm();
                if (!std::isfinite(best) || z < 0.5 || z > 4.5) continue;
                const Eigen::Vector3d q = ray_s * (z + noise(rng));
                const auto idx = *view.points.insert(to_point(q));
                colors.set(idx, {label, 0, 0});
                pixels[idx] = static_cast<std::uint32_t>(r * intr.width + c);
            }
        scene.views.push_back(std::move(view));
    }
    return scene;
}

struct Counts {
    std::size_t subject = 0, kept_subject = 0, kept = 0;
};

Counts count_labels(const std::vector<PointCloud>& before, const std::vector<PointCloud>& after) {
    Counts c;
    for (const auto& v : before)
        for (auto i : v.points) c.subject += v.colors().get(i).r == kSubject;
    for (const auto& v : after)
        for (auto i : v.points) {
            c.kept += 1;
            c.kept_subject += v.colors().get(i).r == kSubject;
        }
    return c;
}

}  // namespace

TEST(SubjectExtraction, KeepsTheSeatedFigureAndDropsFloorWallClutterAndPeople) {
    Scene scene = make_scene();
    const auto before = scene.views;
    const Report report = segment::extract_subject(scene.views, {denoise::NoiseModel::kKinectV2});
    const Counts c = count_labels(before, scene.views);
    const double precision = static_cast<double>(c.kept_subject) / c.kept;
    const double recall = static_cast<double>(c.kept_subject) / c.subject;
    EXPECT_GE(precision, 0.99) << report.dump();
    EXPECT_GE(recall, 0.97) << report.dump();
    ASSERT_TRUE(report["ground"]["found"].get<bool>());
    // The ground in the world frame of the (erroneous) rig poses is the floor within the
    // calibration error: normal within 2 deg of z, height within 2 cm.
    const auto ground = segment::world_ground(scene.views);
    ASSERT_TRUE(ground.has_value());
    EXPECT_GT(ground->normal.z(), std::cos(2.0 * kPi / 180));
    EXPECT_LT(std::abs(ground->offset), 0.02);
    EXPECT_GT(ground->margin_m, 0.0);
    EXPECT_LT(ground->margin_m, 0.03);
}

// A rig calibrated only roughly (2 deg and 40 mm per sensor, as a ring before alignment can
// be): the views' floors disagree by several centimetres in the world frame, so pooled they
// spread over a band with a fifth of the points below any one plane. The ground is judged in
// each view's own refit, so it is still found and cut. (Judged on the pooled plane, as before,
// the floor was "no ground" and stayed in the model: a standing man on a floor, issue 35.)
TEST(SubjectExtraction, AFloorSeenThroughARoughCalibrationIsStillTheGround) {
    Scene scene = make_scene(2.0, 40.0);
    const auto before = scene.views;
    const Report report = segment::extract_subject(scene.views, {denoise::NoiseModel::kKinectV2});
    ASSERT_TRUE(report["ground"]["found"].get<bool>()) << report["ground"].dump();
    EXPECT_LT(report["ground"]["fit_rms_m"].get<double>(), 0.004) << report["ground"].dump();
    const Counts c = count_labels(before, scene.views);
    EXPECT_GE(static_cast<double>(c.kept_subject) / c.kept, 0.98) << report.dump();
    EXPECT_GE(static_cast<double>(c.kept_subject) / c.subject, 0.95) << report.dump();
}

// The views' ground and wall fits run in parallel: one thread gives the same report (times
// aside) and keeps the same points as all of them.
TEST(SubjectExtraction, OneThreadGivesTheSameResult) {
    Scene all = make_scene(2.0, 40.0);
    Scene one = make_scene(2.0, 40.0);
    Report all_report = segment::extract_subject(all.views, {denoise::NoiseModel::kKinectV2});
    Report one_report;
    {
        tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 1);
        one_report = segment::extract_subject(one.views, {denoise::NoiseModel::kKinectV2});
    }
    const std::function<void(Report&)> drop_times = [&](Report& r) {
        if (r.is_object()) {
            for (auto it = r.begin(); it != r.end();)
                if (it.key().find("time") != std::string::npos)
                    it = r.erase(it);
                else
                    drop_times(*it++);
        } else if (r.is_array()) {
            for (auto& x : r) drop_times(x);
        }
    };
    drop_times(all_report);
    drop_times(one_report);
    EXPECT_EQ(all_report, one_report) << all_report.dump() << "\n" << one_report.dump();
    ASSERT_EQ(all.views.size(), one.views.size());
    for (std::size_t v = 0; v < all.views.size(); ++v) {
        ASSERT_EQ(all.views[v].size(), one.views[v].size()) << "view " << v;
        auto a = all.views[v].points.begin();
        for (auto i : one.views[v].points)
            ASSERT_EQ(one.views[v].points.point(i), all.views[v].points.point(*a++))
                << "view " << v;
    }
}

// The wall at x = 3 m (flat, nothing behind it, every sensor in front of it) is a wall (step
// 1b); no face of the figure is (sensors on both sides, or the scene behind it).
TEST(SubjectExtraction, TheRoomsWallIsAWallAndTheFigureHasNone) {
    Scene scene = make_scene();
    const Report report = segment::extract_subject(scene.views, {denoise::NoiseModel::kKinectV2});
    int walls = 0;
    for (const auto& w : report["walls"]) {
        if (!w["found"].get<bool>()) continue;
        ++walls;
        EXPECT_LT(w["normal"][0].get<double>(), -0.99) << w.dump();  // faces the ring, -x
    }
    EXPECT_EQ(walls, 1) << report["walls"].dump();
    const Counts c = count_labels(make_scene().views, scene.views);
    EXPECT_GE(static_cast<double>(c.kept_subject) / c.subject, 0.97) << report.dump();
}

// A wall whose plane passes through a sensor (view 0, the rig's exact one, stands in it and
// looks away from it): that sensor sees the wall edge-on and tells neither side; the others are
// in front of it. It is still a wall (the APC shelf's arm takes a view 3 mm off a side wall's
// plane).
TEST(SubjectExtraction, AWallThroughASensorIsStillAWall) {
    const double x0 = 1.5 * std::cos(0.3);  // view 0's x
    Scene scene = make_scene(1.0, 10.0, true, true, false, false, x0);
    const Report report = segment::extract_subject(scene.views, {denoise::NoiseModel::kKinectV2});
    // The walls that cut points (a later round may find the cut wall's leftover samples again,
    // 2 cm behind it, with a few stray points left to cut: 0-3 of the wall's 57,000).
    int walls = 0;
    for (const auto& w : report["walls"]) {
        if (!w["found"].get<bool>() || w["removed"].get<std::size_t>() < 100) continue;
        ++walls;
        EXPECT_LT(w["normal"][0].get<double>(), -0.99) << w.dump();
        EXPECT_NEAR(-w["offset_m"].get<double>() * w["normal"][0].get<double>(), x0, 0.01)
            << w.dump();
    }
    EXPECT_EQ(walls, 1) << report["walls"].dump();
    const Counts c =
        count_labels(make_scene(1.0, 10.0, true, true, false, false, x0).views, scene.views);
    EXPECT_GE(static_cast<double>(c.kept_subject) / c.subject, 0.97) << report.dump();
}

// A ball standing on nothing: its top faces up and is the lowest plane facing up the RANSAC
// finds, but it is no ground (curved beyond the sensor's noise, the ball below it) and no
// face of it is a wall: the whole ball is kept.
TEST(SubjectExtraction, ABallOnNothingHasNoGroundAndNoWall) {
    Scene scene = make_scene(1.0, 10.0, true, false, false, /*ball=*/true);
    const auto before = scene.views;
    const Report report = segment::extract_subject(scene.views, {denoise::NoiseModel::kKinectV2});
    EXPECT_FALSE(report["ground"]["found"].get<bool>()) << report["ground"].dump();
    for (const auto& w : report["walls"]) EXPECT_FALSE(w["found"].get<bool>()) << w.dump();
    // Refused by the flatness in sensor-noise units (measured 4.2 sigma_z; a floor: 0.5), not
    // only by the ball below it.
    EXPECT_GT(report["ground"]["flatness_sigmas"].get<double>(),
              segment::SubjectOptions{}.ground_flat_sigmas)
        << report["ground"].dump();
    const Counts c = count_labels(before, scene.views);
    EXPECT_GE(static_cast<double>(c.kept_subject) / c.subject, 0.99) << report.dump();
}

TEST(SubjectExtraction, ASensorLookingElsewhereDoesNotChangeTheSubject) {
    Scene scene = make_scene(1.0, 10.0, true, true, /*look_away=*/true);
    const auto before = scene.views;
    const Report report = segment::extract_subject(scene.views, {denoise::NoiseModel::kKinectV2});
    const Counts c = count_labels(before, scene.views);
    EXPECT_GE(static_cast<double>(c.kept_subject) / c.kept, 0.99) << report.dump();
    EXPECT_GE(static_cast<double>(c.kept_subject) / c.subject, 0.97) << report.dump();
}

TEST(SubjectExtraction, GroundOnlyKeepsTheRoomAndKeepGroundKeepsTheFloor) {
    Scene scene = make_scene();
    const auto before = scene.views;
    segment::SubjectOptions options;
    options.select_subject = false;
    segment::extract_subject(scene.views, {denoise::NoiseModel::kKinectV2}, options);
    std::size_t floor_left = 0, background_left = 0;
    for (const auto& v : scene.views)
        for (auto i : v.points) {
            floor_left += v.colors().get(i).r == kGround;
            background_left += v.colors().get(i).r == kBackground;
        }
    EXPECT_LT(floor_left, 100u);
    EXPECT_GT(background_left, 10000u);

    scene.views = before;
    options.select_subject = true;
    options.remove_ground = false;
    const Report report =
        segment::extract_subject(scene.views, {denoise::NoiseModel::kKinectV2}, options);
    EXPECT_FALSE(segment::world_ground(scene.views).has_value());
    EXPECT_FALSE(report["ground"]["found"].get<bool>());
}

TEST(SubjectExtraction, NothingAboveTheGroundIsAnError) {
    Scene scene = make_scene(1.0, 10.0, /*subject=*/false, /*clutter=*/false);
    try {
        segment::extract_subject(scene.views, {denoise::NoiseModel::kKinectV2});
        FAIL() << "expected an InputError";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("nothing above the ground"), std::string::npos)
            << e.what();
    }
}

TEST(SubjectExtraction, ViewsWithoutPosesAreLeftAsTheyAre) {
    Scene scene = make_scene();
    scene.views[2].view.world_from_sensor.reset();
    const std::size_t before = scene.views[0].size();
    const Report report = segment::extract_subject(scene.views, {denoise::NoiseModel::kKinectV2});
    EXPECT_TRUE(report.contains("note"));
    EXPECT_EQ(scene.views[0].size(), before);
}

TEST(SubjectExtraction, TheCropOverridesTheRegions) {
    Scene scene = make_scene();
    segment::SubjectOptions options;
    options.crop_centre = Eigen::Vector3d(0, 0, 0.8);
    options.crop_radius_m = 0.4;  // cuts the head and the feet off
    const auto before = scene.views;
    const Report report =
        segment::extract_subject(scene.views, {denoise::NoiseModel::kKinectV2}, options);
    EXPECT_TRUE(report.contains("crop"));
    for (const auto& v : scene.views)
        for (auto i : v.points)
            EXPECT_LE(((*v.view.world_from_sensor) * to_eigen(v.points.point(i)) -
                       Eigen::Vector3d(0, 0, 0.8))
                          .norm(),
                      0.4 + 1e-9);
    const Counts c = count_labels(before, scene.views);
    EXPECT_LT(static_cast<double>(c.kept_subject) / c.subject, 0.9);
}

TEST(SubjectExtraction, MalformedGroundMetadataIsAnError) {
    PointCloud view;
    view.view.id = 3;
    view.view.extra_comments.push_back(std::string(segment::kGroundKey) + "0 0 2 0.1 0.01");
    EXPECT_THROW(segment::view_ground(view), InputError);
    view.view.extra_comments = {std::string(segment::kGroundKey) + "0 0 1 nan 0.01"};
    EXPECT_THROW(segment::view_ground(view), InputError);
    view.view.extra_comments = {std::string(segment::kGroundKey) + "0 0 1 -0.5 0.01"};
    const auto g = segment::view_ground(view);
    ASSERT_TRUE(g.has_value());
    EXPECT_DOUBLE_EQ(g->offset, -0.5);
}

TEST(SubjectExtraction, AbsurdOptionsAreRefused) {
    segment::SubjectOptions o;
    o.core_share = 1.5;
    EXPECT_THROW(o.check(), InputError);
    o = {};
    o.ground_band_m = std::nan("");
    EXPECT_THROW(o.check(), InputError);
    o = {};
    o.solid_points = 0;
    EXPECT_THROW(o.check(), InputError);
}
