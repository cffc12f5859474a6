#include "algorithms/sampling/merge_views.hpp"

#include <gtest/gtest.h>

#include <cmath>

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

// The merge copies column by column into a point set sized once (Point_set_3::join sorted
// the growing result at every view): the same points, in the same order, with the same
// properties as joining the views one after the other, also for views with removed points,
// normals and a property only some views have.
TEST(MergeViews, SameAsJoiningViewByView) {
    std::vector<PointCloud> views, copies;
    for (int v = 0; v < 5; ++v) {
        PointCloud cloud = view_with(v + 1, 50 + 13 * v, /*colors=*/v % 2 == 0,
                                     /*confidence=*/v == 3);
        cloud.points.add_normal_map();
        int i = 0;
        for (auto idx : cloud.points) {
            cloud.points.point(idx) = rgbd::Point_3(v, i * 0.01, std::sin(i + v));
            cloud.points.normal(idx) = rgbd::Vector_3(0, std::cos(i), std::sin(i));
            ++i;
        }
        // Remove every seventh point (marked removed, not collected).
        std::vector<rgbd::PointSet::Index> doomed;
        i = 0;
        for (auto idx : cloud.points)
            if (i++ % 7 == 3) doomed.push_back(idx);
        for (auto it = doomed.rbegin(); it != doomed.rend(); ++it) cloud.points.remove(*it);
        copies.push_back(cloud);
        views.push_back(std::move(cloud));
    }
    rgbd::PointSet reference;
    for (auto& c : copies) reference.copy_properties(c.points);
    auto ref_view = reference.add_property_map<std::int32_t>("view", 0).first;
    for (auto& c : copies) {
        const std::size_t begin = reference.size();
        reference.join(c.points);
        for (std::size_t i = begin; i < reference.size(); ++i)
            ref_view[rgbd::PointSet::Index(std::uint32_t(i))] = c.view.id;
    }
    const PointCloud merged = rgbd::sampling::merge_views(std::move(views));
    ASSERT_EQ(merged.size(), reference.size());
    ASSERT_TRUE(merged.points.has_normal_map());
    const auto ids = merged.view_map();
    ASSERT_TRUE(ids.has_value());
    const auto colors = merged.colors();
    const auto conf = merged.float_map(rgbd::prop::kConfidence);
    ASSERT_TRUE(conf.has_value());
    const auto ref_r = reference.property_map<std::uint8_t>(rgbd::prop::kRed).first;
    const auto ref_conf = reference.property_map<float>(rgbd::prop::kConfidence).first;
    auto a = merged.points.begin();
    auto b = reference.begin();
    for (; a != merged.points.end(); ++a, ++b) {
        EXPECT_EQ(merged.points.point(*a), reference.point(*b));
        EXPECT_EQ(merged.points.normal(*a), reference.normal(*b));
        EXPECT_EQ((*ids)[*a], ref_view[*b]);
        EXPECT_EQ(colors.get(*a).r, ref_r[*b]);
        EXPECT_EQ((*conf)[*a], ref_conf[*b]);
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
