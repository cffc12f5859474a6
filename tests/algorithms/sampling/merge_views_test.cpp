#include "algorithms/sampling/merge_views.hpp"

#include <gtest/gtest.h>

#include "toolkit/error.hpp"

namespace {

using rgbd::PointCloud;

PointCloud view_with(int id, int n, bool colors, bool confidence) {
    PointCloud cloud;
    cloud.view.id = id;
    cloud.view.sensor = "k2-" + std::to_string(id);
    cloud.view.frame = rgbd::ViewFrame::kWorld;
    cloud.view.history = {"rgbd-cloud 0.1.0",
                          "rgbd-clean 0.1.0 --distance view" + std::to_string(id)};
    for (int i = 0; i < n; ++i) cloud.points.insert(rgbd::Point_3(id, i, 0));
    if (colors)
        for (auto idx : cloud.points) cloud.add_colors().set(idx, {200, 10, 10});
    if (confidence)
        for (auto idx : cloud.points) cloud.add_float(rgbd::prop::kConfidence)[idx] = 0.5f;
    return cloud;
}

TEST(MergeViews, ConcatenatesWithViewIdsAndPropertyUnion) {
    std::vector<PointCloud> views;
    views.push_back(view_with(3, 4, /*colors=*/true, /*confidence=*/false));
    views.push_back(view_with(7, 2, /*colors=*/false, /*confidence=*/true));
    const PointCloud merged = rgbd::sampling::merge_views(std::move(views));
    ASSERT_EQ(merged.size(), 6u);
    EXPECT_EQ(merged.view.sensor, "merged");
    EXPECT_EQ(merged.view.id, 0);
    EXPECT_EQ(merged.view.frame, rgbd::ViewFrame::kWorld);
    EXPECT_FALSE(merged.view.has_grid());
    EXPECT_FALSE(merged.view.world_from_sensor.has_value());
    ASSERT_EQ(merged.view.history.size(), 3u);
    const auto ids = merged.view_map();
    ASSERT_TRUE(ids.has_value());
    ASSERT_TRUE(merged.has_colors());
    const auto conf = merged.float_map(rgbd::prop::kConfidence);
    ASSERT_TRUE(conf.has_value());
    const auto colors = merged.colors();
    int i = 0;
    for (auto idx : merged.points) {
        const bool first = i < 4;
        EXPECT_EQ((*ids)[idx], first ? 3 : 7);
        EXPECT_EQ(merged.points.point(idx).x(), first ? 3.0 : 7.0);
        EXPECT_EQ(colors.get(idx), first ? (rgbd::Rgb{200, 10, 10}) : (rgbd::Rgb{0, 0, 0}));
        EXPECT_EQ((*conf)[idx], first ? 0.0f : 0.5f);
        ++i;
    }
}

TEST(MergeViews, SensorFrameViewsAreMovedToTheWorld) {
    std::vector<PointCloud> views;
    views.push_back(view_with(0, 1, false, false));
    PointCloud sensor = view_with(1, 1, false, false);
    sensor.view.frame = rgbd::ViewFrame::kSensor;
    rgbd::Pose pose = rgbd::Pose::Identity();
    pose.translation() = Eigen::Vector3d(0, 0, 2);
    sensor.view.world_from_sensor = pose;
    views.push_back(sensor);
    const PointCloud merged = rgbd::sampling::merge_views(std::move(views));
    auto it = merged.points.begin();
    ++it;
    EXPECT_EQ(merged.points.point(*it), rgbd::Point_3(1, 0, 2));

    std::vector<PointCloud> bad;
    PointCloud no_pose = view_with(5, 1, false, false);
    no_pose.view.frame = rgbd::ViewFrame::kSensor;
    bad.push_back(no_pose);
    EXPECT_THROW(rgbd::sampling::merge_views(std::move(bad)), rgbd::InputError);
}

TEST(MergeViews, ConflictingPropertyTypesAreRejected) {
    std::vector<PointCloud> views;
    views.push_back(view_with(0, 1, false, false));
    views.back().points.add_property_map<float>("quality", 1.0f);
    views.push_back(view_with(1, 1, false, false));
    views.back().points.add_property_map<double>("quality", 1.0);
    EXPECT_THROW(rgbd::sampling::merge_views(std::move(views)), rgbd::InputError);
    EXPECT_EQ(rgbd::sampling::merge_views({}).size(), 0u);
}

}  // namespace
