// Unit tests of algorithms/calibration: the board description, detection of a rendered board
// at a known pose (with the depth check of its plane), and the joint rig solve on observations
// with a known answer (a ring of cameras, boards in random poses, pixel noise), including the
// cameras it cannot connect.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <random>

#include "algorithms/calibration/charuco_board.hpp"
#include "algorithms/calibration/rig_refinement.hpp"
#include "algorithms/calibration/rig_solver.hpp"
#include "toolkit/error.hpp"
#include "validation/synth/charuco_scene.hpp"
#include "validation/synth/synthesize.hpp"

using namespace rgbd;
using calibration::BoardSpec;

namespace {

PinholeIntrinsics kinect_color() { return synth::kinect_v2_spec("k").color; }

/// Renders the board (grey print on a white plate) seen by a camera at world_from_camera.
cv::Mat render_board(const BoardSpec& board, const Pose& world_from_board,
                     const Pose& world_from_camera, const PinholeIntrinsics& k) {
    const double ppm = 4000;
    cv::Mat printed = calibration::board_image(board, ppm);
    const double w = board.width_m(), h = board.height_m(), m = 0.02;
    std::vector<Eigen::Vector3d> v = {
        {-m, -m, 0}, {w + m, -m, 0}, {w + m, h + m, 0}, {-m, h + m, 0}};
    for (auto& p : v) p = world_from_board * p;
    const synth::RenderScene scene(v, {{0, 1, 2}, {0, 2, 3}});
    const Pose board_from_world = world_from_board.inverse();
    return synth::render_color(
        scene, k, world_from_camera,
        [&](const Eigen::Vector3d& p, int) {
            const Eigen::Vector3d b = board_from_world * p;
            const int c = static_cast<int>(b.x() * ppm), r = static_cast<int>(b.y() * ppm);
            const std::uint8_t g = c >= 0 && r >= 0 && c < printed.cols && r < printed.rows
                                       ? printed.at<std::uint8_t>(r, c)
                                       : 230;
            return Rgb{g, g, g};
        },
        Rgb{64, 64, 64});
}

Pose board_in_front(double distance_m, double yaw_deg) {
    BoardSpec b;
    Pose p = Pose::Identity();
    p.linear() = Eigen::AngleAxisd(yaw_deg * std::numbers::pi / 180, Eigen::Vector3d::UnitY())
                     .toRotationMatrix();
    p.translation() = Eigen::Vector3d(0, 0, distance_m) -
                      p.linear() * Eigen::Vector3d(0.5 * b.width_m(), 0.5 * b.height_m(), 0);
    return p;  // camera at the origin looking along +z
}

}  // namespace

TEST(BoardSpec, DefaultsJsonAndErrors) {
    const BoardSpec b;
    EXPECT_EQ(b.corner_count(), 24);
    EXPECT_NEAR(b.corner(0).x(), 0.08, 1e-12);
    EXPECT_NEAR(b.corner(6).y(), 0.16, 1e-12);  // second row of 6 inner corners
    const BoardSpec c = BoardSpec::from_json(b.to_json());
    EXPECT_EQ(c.squares_x, 7);
    EXPECT_EQ(c.dictionary, "DICT_5X5_100");
    EXPECT_THROW(BoardSpec::from_json({{"square_m", -1.0}}), InputError);
    EXPECT_THROW(BoardSpec::from_json({{"marker_m", 0.09}}), InputError);  // larger than square
    EXPECT_THROW(BoardSpec::from_json({{"dictionary", "DICT_9X9"}}), InputError);
    EXPECT_THROW(BoardSpec::from_json({{"squares", 7}}), InputError);  // unknown key
    EXPECT_THROW(BoardSpec::from_json({{"squares_x", "seven"}}), InputError);
    // 30 x 30 squares need 450 markers: DICT_5X5_100 has 100.
    EXPECT_THROW(BoardSpec::from_json({{"squares_x", 30}, {"squares_y", 30}}), InputError);
}

TEST(BoardImage, CornersWhereTheSpecSays) {
    const BoardSpec b;
    const cv::Mat image = calibration::board_image(b, 2000);
    EXPECT_EQ(image.cols, 1120);
    EXPECT_EQ(image.rows, 800);
    // A camera looking straight at the printed image: fx = 1 px per pixel at unit depth.
    PinholeIntrinsics k;
    k.width = image.cols;
    k.height = image.rows;
    k.fx = k.fy = 1000;
    k.cx = k.cy = 0;
    const auto out = calibration::detect_board(image, k, b);
    ASSERT_TRUE(out.observation) << out.rejected;
    EXPECT_EQ(out.observation->ids.size(), 24u);
    for (std::size_t i = 0; i < out.observation->ids.size(); ++i) {
        const Eigen::Vector3d c = b.corner(out.observation->ids[i]);
        EXPECT_NEAR(out.observation->pixels[i].x(), c.x() * 2000 - 0.5, 0.6);
        EXPECT_NEAR(out.observation->pixels[i].y(), c.y() * 2000 - 0.5, 0.6);
    }
}

TEST(DetectBoard, PoseOfARenderedBoard) {
    const BoardSpec b;
    const PinholeIntrinsics k = kinect_color();
    for (double yaw : {0.0, 35.0, -50.0}) {
        SCOPED_TRACE(yaw);
        const Pose truth = board_in_front(1.6, yaw);
        const cv::Mat image = render_board(b, truth, Pose::Identity(), k);
        const auto out = calibration::detect_board(image, k, b);
        ASSERT_TRUE(out.observation) << out.rejected;
        EXPECT_GE(out.observation->ids.size(), 20u);
        EXPECT_LT(out.observation->rms_px, 0.5);
        EXPECT_LT(rotation_error_deg(out.observation->camera_from_board, truth), 0.5);
        // One view's PnP: the depth along the ray is the weak direction (a few mm at 1.6 m).
        EXPECT_LT(translation_error_m(out.observation->camera_from_board, truth), 0.01);
    }
    // No board: an empty grey image.
    const cv::Mat grey(k.height, k.width, CV_8UC3, cv::Scalar(64, 64, 64));
    const auto none = calibration::detect_board(grey, k, b);
    EXPECT_FALSE(none.observation);
    EXPECT_EQ(none.markers, 0);
    // Another dictionary finds nothing of this board.
    BoardSpec other = b;
    other.dictionary = "DICT_6X6_100";
    const cv::Mat image = render_board(b, board_in_front(1.6, 0), Pose::Identity(), k);
    EXPECT_FALSE(calibration::detect_board(image, k, other).observation);
}

TEST(DetectBoard, HalfVisibleBoard) {
    const BoardSpec b;
    const PinholeIntrinsics k = kinect_color();
    // Half of the board beyond the right edge of the image (its centre on the edge): the
    // corners of the visible half give the pose.
    const double distance = 1.6;
    const double edge_x = distance * (k.width - 1 - k.cx) / k.fx;
    Pose truth = board_in_front(distance, 20.0);
    truth.translation().x() += edge_x;
    const auto half = calibration::detect_board(render_board(b, truth, Pose::Identity(), k), k, b);
    ASSERT_TRUE(half.observation) << half.rejected;
    EXPECT_GE(half.observation->ids.size(), 6u);
    EXPECT_LT(half.observation->ids.size(), 20u);  // not the whole board
    for (const auto& px : half.observation->pixels) EXPECT_LT(px.x(), k.width);
    EXPECT_LT(rotation_error_deg(half.observation->camera_from_board, truth), 0.5);
    EXPECT_LT(translation_error_m(half.observation->camera_from_board, truth), 0.015);
    // Only a sliver in view (the last 10 cm of the board): no observation, and a reason when
    // markers were seen.
    Pose sliver = board_in_front(distance, 0.0);
    sliver.translation().x() += edge_x + 0.5 * b.width_m() - 0.1;
    const auto out = calibration::detect_board(render_board(b, sliver, Pose::Identity(), k), k, b);
    EXPECT_FALSE(out.observation);
    if (out.markers > 0) {
        EXPECT_FALSE(out.rejected.empty());
    }
}

TEST(CombinedDepth, NoiseAveragedAndMovingPixelsLeftOut) {
    // 9 frames of a plane at 1.5 m with Gaussian noise of 2 mm, random dropouts, and a strip
    // of pixels that something moved through in 5 of the frames.
    std::mt19937 rng(3);
    std::normal_distribution<float> noise(0.0f, 0.002f);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    std::vector<cv::Mat> depths;
    for (int f = 0; f < 9; ++f) {
        cv::Mat d(40, 50, CV_32FC1);
        for (int r = 0; r < d.rows; ++r)
            for (int c = 0; c < d.cols; ++c) {
                float z = 1.5f + noise(rng);
                if (u(rng) < 0.1f) z = std::numeric_limits<float>::quiet_NaN();
                if (c < 5 && f >= 2 && f < 7) z = 0.6f + 0.1f * f;  // a hand passing
                if (c >= 45 && f < 5) z = 0.0f;                     // invalid (0) in 5 of 9 frames
                d.at<float>(r, c) = z;
            }
        depths.push_back(d);
    }
    const cv::Mat m = calibration::combined_depth(depths);
    ASSERT_EQ(m.type(), CV_32FC1);
    double sum = 0, sq = 0;
    int n = 0, lost = 0;
    for (int r = 0; r < m.rows; ++r)
        for (int c = 0; c < m.cols; ++c) {
            const float z = m.at<float>(r, c);
            if (c < 5 || c >= 45) {
                EXPECT_TRUE(std::isnan(z)) << r << " " << c << " " << z;
                continue;
            }
            if (!std::isfinite(z)) {  // 5 or more of the 9 frames dropped it (p ~ 0.001)
                ++lost;
                continue;
            }
            sum += z - 1.5;
            sq += (z - 1.5) * (z - 1.5);
            ++n;
        }
    EXPECT_LE(lost, 10);
    // The mean of ~8 samples: noise down from 2 mm to ~0.7 mm, no bias.
    EXPECT_LT(std::abs(sum / n), 2e-4);
    EXPECT_LT(std::sqrt(sq / n), 0.0011);
    EXPECT_GT(std::sqrt(sq / n), 0.0004);
    // One frame comes back unchanged; bad input is an InputError.
    const cv::Mat one = calibration::combined_depth({depths[0]});
    ASSERT_EQ(one.size(), depths[0].size());
    EXPECT_EQ(std::memcmp(one.data, depths[0].data, one.total() * sizeof(float)), 0);
    EXPECT_THROW(calibration::combined_depth({}), InputError);
    EXPECT_THROW(calibration::combined_depth({depths[0], cv::Mat(10, 10, CV_32FC1)}), InputError);
    EXPECT_THROW(calibration::combined_depth({depths[0], depths[1]}, -1.0), InputError);
}

TEST(CombinedDepth, QuantisedDepthsAveragedToTheirNoiseOverRootN) {
    // 8 frames of a slanted surface (1.5-1.51 m) with Kinect v2's noise at 1.5 m (1.4 mm),
    // stored like the sensors' depth images in whole millimetres. The combination reaches the
    // sigma / sqrt(8) of a mean, without bias; a median of the 8 values (the earlier
    // combination) leaves ~1.2 sigma / sqrt(8) and moves in 0.5 mm steps.
    std::mt19937 rng(5);
    const double sigma = 0.0014;
    std::normal_distribution<double> noise(0.0, sigma);
    const int rows = 40, cols = 60, frames = 8;
    cv::Mat truth(rows, cols, CV_64FC1);
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c)
            truth.at<double>(r, c) = 1.5 + 0.01 * (r * cols + c) / (rows * cols);
    std::vector<cv::Mat> depths;
    for (int f = 0; f < frames; ++f) {
        cv::Mat d(rows, cols, CV_32FC1);
        for (int r = 0; r < rows; ++r)
            for (int c = 0; c < cols; ++c)
                d.at<float>(r, c) = static_cast<float>(
                    std::round((truth.at<double>(r, c) + noise(rng)) * 1000) / 1000);
        depths.push_back(d);
    }
    const cv::Mat m = calibration::combined_depth(depths);
    double sum = 0, sq = 0;
    int n = 0, off_grid = 0;
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            const double z = m.at<float>(r, c);
            ASSERT_TRUE(std::isfinite(z));
            const double e = z - truth.at<double>(r, c);
            sum += e;
            sq += e * e;
            ++n;
            // Not on the 0.5 mm grid of a median of whole millimetres.
            off_grid += std::abs(z * 2000 - std::round(z * 2000)) > 0.05;
        }
    const double rms = std::sqrt(sq / n);
    EXPECT_LT(rms, 1.08 * sigma / std::sqrt(double(frames)));
    EXPECT_LT(std::abs(sum / n), 4e-5);
    EXPECT_GT(off_grid, n / 2);
}

TEST(RigRefinement, OptionsAreValidAndJointFromTheRig) {
    const auto o = calibration::rig_refinement_options(2, 7);
    EXPECT_NO_THROW(o.check());
    EXPECT_EQ(o.fixed_view, 2u);
    EXPECT_FALSE(o.pairwise);
    EXPECT_EQ(o.rounds, static_cast<int>(o.icp.max_distance_factors.size()));
    EXPECT_GE(o.icp.max_distance_factors.front() * 0.004, 0.1);  // ~10 cm at a 4 mm spacing
}

TEST(CheckBoardPlane, ResidualOfADepthImage) {
    const BoardSpec b;
    PinholeIntrinsics k = synth::kinect_v2_spec("k").depth;
    const Pose truth = board_in_front(1.5, 20);
    std::vector<Eigen::Vector3d> v = {
        {0, 0, 0}, {b.width_m(), 0, 0}, {b.width_m(), b.height_m(), 0}, {0, b.height_m(), 0}};
    for (auto& p : v) p = truth * p;
    const synth::RenderScene scene(v, {{0, 1, 2}, {0, 2, 3}});
    const cv::Mat depth = synth::render_depth(scene, k, Pose::Identity()).depth_float();
    const auto exact = calibration::check_board_plane(depth, k, b, truth);
    EXPECT_GT(exact.pixels, 1000);
    EXPECT_NEAR(exact.median_mm, 0.0, 0.05);
    EXPECT_LT(exact.rms_mm, 0.05);
    // The board placed 10 mm nearer than the depth says: the depth lies 10 mm behind it.
    Pose nearer = truth;
    nearer.translation() -= 0.01 * truth.linear().col(2);
    const auto off = calibration::check_board_plane(depth, k, b, nearer);
    EXPECT_NEAR(off.median_mm, 10.0, 0.2);
}

namespace {

/// A ring of n cameras 1.5 m from the centre, boards in random poses near the centre, each seen
/// by the cameras in front of it; pixel noise sigma_px; PnP-like starts perturbed.
struct RingProblem {
    std::vector<Pose> world_from_camera;
    std::vector<calibration::Observation> observations;
};

RingProblem make_ring(int n, int boards, double sigma_px, unsigned seed) {
    const BoardSpec b;
    const PinholeIntrinsics k = kinect_color();
    RingProblem out;
    for (int i = 0; i < n; ++i) {
        const double phi = 2 * std::numbers::pi * i / n;
        out.world_from_camera.push_back(synth::look_at(
            {1.5 * std::cos(phi), 1.5 * std::sin(phi), 1.6}, Eigen::Vector3d(0, 0, 1.3)));
    }
    std::mt19937 rng(seed);
    std::normal_distribution<double> noise(0.0, sigma_px), small(0.0, 0.01);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int f = 0; f < boards; ++f) {
        const int target = f % n;
        const Eigen::Vector3d c(0.2 * u(rng), 0.2 * u(rng), 1.3 + 0.2 * u(rng));
        const Eigen::Vector3d towards =
            (out.world_from_camera[target].translation() +
             0.5 * (out.world_from_camera[(target + 1) % n].translation() -
                    out.world_from_camera[target].translation()) -
             c)
                .normalized();
        Pose frame = synth::look_at(c, c - towards);
        Pose origin = Pose::Identity();
        origin.translation() = Eigen::Vector3d(-0.5 * b.width_m(), -0.5 * b.height_m(), 0);
        const Pose world_from_board = frame * origin;
        for (int i = 0; i < n; ++i) {
            const Pose camera_from_board = out.world_from_camera[i].inverse() * world_from_board;
            // Seen when the camera is in front (board z points away from it) within 60 degrees.
            const Eigen::Vector3d to_camera =
                (out.world_from_camera[i].translation() - world_from_board.translation())
                    .normalized();
            if (-world_from_board.linear().col(2).dot(to_camera) <
                std::cos(60 * std::numbers::pi / 180))
                continue;
            calibration::Observation o;
            o.sensor = i;
            o.frameset = f;
            for (int id = 0; id < b.corner_count(); ++id) {
                const Eigen::Vector2d px = k.project(camera_from_board * b.corner(id));
                o.board.ids.push_back(id);
                o.board.pixels.push_back(px + Eigen::Vector2d(noise(rng), noise(rng)));
            }
            Pose start = camera_from_board;
            start.linear() =
                start.linear() *
                Eigen::AngleAxisd(small(rng), Eigen::Vector3d::UnitX()).toRotationMatrix();
            start.translation() += Eigen::Vector3d(small(rng), small(rng), 3 * small(rng));
            o.board.camera_from_board = start;
            o.board.rms_px = 0.3;
            out.observations.push_back(o);
        }
    }
    return out;
}

}  // namespace

TEST(SolveRig, RecoversARingOfCameras) {
    for (int n : {4, 6, 8})
        for (double sigma : {0.0, 0.3}) {
            SCOPED_TRACE(std::to_string(n) + " cameras, " + std::to_string(sigma) + " px");
            const RingProblem ring = make_ring(n, 5 * n, sigma, 7 + n);
            const std::vector<PinholeIntrinsics> k(n, kinect_color());
            const auto sol = calibration::solve_rig(k, ring.observations, BoardSpec{});
            EXPECT_TRUE(sol.unconnected.empty());
            EXPECT_LT(sol.final_rms_px, 1.5 * sigma + 1e-6);  // sigma per axis: ~1.4 sigma
            EXPECT_LT(sol.final_rms_px, sol.initial_rms_px);
            const Pose world_from_anchor = ring.world_from_camera[0];
            // Noise-free: exact (acos resolves ~1e-6 deg). 0.3 px: the target (0.3 deg),
            // and the camera centres within 5 mm (1.5 m away; what matters at the object is checked
            // by the tool test).
            const double max_deg = sigma > 0 ? 0.3 : 1e-4, max_m = sigma > 0 ? 0.005 : 1e-6;
            for (int i = 0; i < n; ++i) {
                const Pose truth = world_from_anchor.inverse() * ring.world_from_camera[i];
                EXPECT_LT(rotation_error_deg(sol.cameras[i].anchor_from_camera, truth), max_deg)
                    << i;
                EXPECT_LT(translation_error_m(sol.cameras[i].anchor_from_camera, truth), max_m)
                    << i;
            }
        }
}

TEST(SolveRig, NamesCamerasItCannotConnect) {
    RingProblem ring = make_ring(6, 30, 0.3, 3);
    // Camera 3 sees boards only in frame sets of its own.
    for (auto& o : ring.observations)
        if (o.sensor == 3) o.frameset += 1000;
    const std::vector<PinholeIntrinsics> k(6, kinect_color());
    EXPECT_EQ(calibration::unconnected_cameras(6, ring.observations, 0), std::vector<int>{3});
    const auto sol = calibration::solve_rig(k, ring.observations, BoardSpec{});
    EXPECT_EQ(sol.unconnected, std::vector<int>{3});
    EXPECT_FALSE(sol.cameras[3].connected);
    calibration::RigSolveOptions bad;
    bad.anchor = 6;
    EXPECT_THROW(calibration::solve_rig(k, ring.observations, BoardSpec{}, bad), InputError);
    EXPECT_THROW(calibration::solve_rig(k, {}, BoardSpec{}), AlgorithmError);
}

TEST(CharucoScene, BoardPosesStayInTheBall) {
    synth::SynthOptions o;
    synth::BoardMotion m;
    std::vector<Eigen::Vector3d> sensors;
    for (int i = 0; i < 8; ++i)
        sensors.emplace_back(1.5 * std::cos(i * std::numbers::pi / 4),
                             1.5 * std::sin(i * std::numbers::pi / 4), 1.6);
    const Eigen::Vector3d centre(0, 0, 1.33);
    for (int f = 0; f < 50; ++f) {
        const Pose p = synth::board_pose(m, o, f, centre, sensors);
        const Eigen::Vector3d mid = p * Eigen::Vector3d(0.28, 0.2, 0);
        EXPECT_LE((mid - centre).norm(), m.radius_m + 1e-9);
        EXPECT_NEAR(p.linear().determinant(), 1.0, 1e-9);
    }
}
