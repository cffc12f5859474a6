// pipeline::source_measurements, the free-space evidence read again from the views' own depth
// frames (rgbd:view.source): on a synthetic capture of a sphere with exact depth
// (examples/example_data.hpp), every valid pixel of every view comes back on the sphere, inside
// the box asked for, moved by the view's current (aligned) pose rather than the capture's; a view
// whose frame cannot be found is counted and noted, never an error.
#include "pipeline/source_evidence.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "algorithms/segment/subject_extraction.hpp"
#include "examples/example_data.hpp"
#include "io/capture_folder.hpp"
#include "tests/support/tool_runner.hpp"

namespace {

const rgbd::io::Capture& capture() {
    static const rgbd::io::Capture c = rgbd::io::open_capture(
        examples::make_capture(rgbd::test::scratch_dir("rgbd_source_evidence_test"), 4));
    return c;
}

/// A view as rgbd-cloud writes it, without its points: the frame's sensor, index, source, pose
/// and intrinsics.
rgbd::PointCloud view_of(const rgbd::RgbdFrame& frame) {
    rgbd::PointCloud view;
    view.view.sensor = frame.sensor_id;
    view.view.frame_index = frame.frame_index;
    view.view.source = frame.source;
    view.view.world_from_sensor = frame.world_from_sensor;
    view.view.intrinsics = frame.depth_intrinsics;
    return view;
}

std::size_t valid_pixels(const rgbd::RgbdFrame& frame) {
    std::size_t n = 0;
    for (int r = 0; r < frame.depth.rows; ++r)
        for (int c = 0; c < frame.depth.cols; ++c) n += frame.depth.at<float>(r, c) > 0;
    return n;
}

TEST(SourceEvidence, EveryValidPixelOfEveryViewComesBackOnTheSphereInsideTheBox) {
    std::vector<rgbd::PointCloud> views;
    std::size_t pixels = 0;
    for (const auto& sensor : capture().rig.sensors) {
        const rgbd::RgbdFrame frame = rgbd::io::load_frame(capture(), sensor.id, 0);
        pixels += valid_pixels(frame);
        views.push_back(view_of(frame));
        EXPECT_EQ(rgbd::pipeline::capture_root_of(frame.source, sensor.id),
                  capture().root.string());
    }
    ASSERT_GT(pixels, 1000u);
    const Eigen::AlignedBox3d everything(Eigen::Vector3d::Constant(-10),
                                         Eigen::Vector3d::Constant(10));
    const auto all = rgbd::pipeline::source_measurements(views, everything);
    EXPECT_EQ(all.frames_read, views.size());
    EXPECT_EQ(all.frames_missing, 0u);
    EXPECT_EQ(all.points.size(), pixels);
    for (const auto& p : all.points) ASSERT_NEAR(p.norm(), examples::kRadius, 0.002);
    // Half the space: only the points inside it, and about half of them.
    const Eigen::AlignedBox3d upper(Eigen::Vector3d(-1, -1, 0), Eigen::Vector3d(1, 1, 1));
    const auto half = rgbd::pipeline::source_measurements(views, upper);
    for (const auto& p : half.points) EXPECT_GE(p.z(), 0.0);
    EXPECT_GT(half.points.size(), pixels / 5);
    EXPECT_LT(half.points.size(), pixels * 4 / 5);
}

TEST(SourceEvidence, TheViewsAlignedPoseMovesItsPointsAMissingFrameIsNotedNotAnError) {
    const rgbd::RgbdFrame frame =
        rgbd::io::load_frame(capture(), capture().rig.sensors.front().id, 0);
    const Eigen::AlignedBox3d everything(Eigen::Vector3d::Constant(-10),
                                         Eigen::Vector3d::Constant(10));
    std::vector<rgbd::PointCloud> views{view_of(frame)};
    const auto original = rgbd::pipeline::source_measurements(views, everything);
    // The alignment moved the view by 1 cm along x: its evidence moves with it.
    rgbd::Pose shifted = rgbd::Pose::Identity();
    shifted.translation() = Eigen::Vector3d(0.01, 0, 0);
    views.front().view.world_from_sensor = shifted * *views.front().view.world_from_sensor;
    const auto moved = rgbd::pipeline::source_measurements(views, everything);
    ASSERT_EQ(moved.points.size(), original.points.size());
    for (std::size_t i = 0; i < moved.points.size(); i += 97)
        EXPECT_NEAR((moved.points[i] - original.points[i]).x(), 0.01, 1e-9);
    // A view whose frame is gone (the capture moved) and one without a source (the fill's
    // points): the first is counted and noted, the second skipped, no error.
    rgbd::PointCloud gone = view_of(frame);
    gone.view.source = "/nonexistent/capture/k0/depth/000000.png";
    rgbd::PointCloud synthetic;
    const auto partial =
        rgbd::pipeline::source_measurements({gone, synthetic, view_of(frame)}, everything);
    EXPECT_EQ(partial.frames_read, 1u);
    EXPECT_EQ(partial.frames_missing, 1u);
    EXPECT_NE(partial.note.find("/nonexistent/capture"), std::string::npos) << partial.note;
    EXPECT_EQ(partial.points.size(), original.points.size());
}

// With a ground band only the pixels near the ground plane the view carries come back (what the
// extraction removed as the ground); a view without a plane gives none.
TEST(SourceEvidence, AGroundBandKeepsThePixelsNearTheViewsGroundPlane) {
    const rgbd::RgbdFrame frame =
        rgbd::io::load_frame(capture(), capture().rig.sensors.front().id, 0);
    const Eigen::AlignedBox3d everything(Eigen::Vector3d::Constant(-10),
                                         Eigen::Vector3d::Constant(10));
    rgbd::PointCloud view = view_of(frame);
    EXPECT_TRUE(rgbd::pipeline::source_measurements({view}, everything, 2.0).points.empty());
    // The world plane z = 0 (through the sphere's centre) in the sensor frame, margin 5 mm.
    const rgbd::Pose& pose = frame.world_from_sensor;
    const Eigen::Vector3d n = pose.linear().transpose() * Eigen::Vector3d::UnitZ();
    const double d = pose.translation().z();  // n . p_sensor + d = z_world
    view.view.extra_comments.push_back(std::string(rgbd::segment::kGroundKey) +
                                       std::to_string(n.x()) + " " + std::to_string(n.y()) + " " +
                                       std::to_string(n.z()) + " " + std::to_string(d) + " 0.005");
    const auto band = rgbd::pipeline::source_measurements({view}, everything, 2.0);
    ASSERT_GT(band.points.size(), 20u);
    for (const auto& p : band.points) EXPECT_LE(std::abs(p.z()), 0.0101);
    EXPECT_LT(band.points.size(),
              rgbd::pipeline::source_measurements({view}, everything).points.size() / 4);
}

}  // namespace
