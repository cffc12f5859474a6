#include "algorithms/registration/duplicate_removal.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>

#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/sampling/merge_views.hpp"
#include "synthetic_views.hpp"
#include "toolkit/error.hpp"

namespace {

using rgbd::PointCloud;
using rgbd::Pose;
using rgbd::Rgb;

/// Two aligned world-frame views of the bumpy ellipsoid 70 degrees apart (about a third of
/// each view overlaps the other), with normals towards the sensor, painted by `paint_b` for the
/// second view.
std::vector<PointCloud> two_views(Rgb paint_a, Rgb paint_b) {
    const rgbd::test::BumpyEllipsoid shape;
    std::vector<PointCloud> views;
    for (int i = 0; i < 2; ++i) {
        const double yaw = (i == 0 ? -35.0 : 35.0) * M_PI / 180.0;
        const Pose t =
            rgbd::test::look_at({0.8 * std::sin(yaw), 0.1, -0.8 * std::cos(yaw)}, shape.centre);
        const Rgb paint = i == 0 ? paint_a : paint_b;
        PointCloud v = rgbd::test::render_view(shape, t, i, 0.0003, 70 + i, 2,
                                               [&](const Eigen::Vector3d&) { return paint; });
        v.points.add_normal_map();
        for (auto idx : v.points) {
            const Eigen::Vector3d p = t * rgbd::to_eigen(v.points.point(idx));
            Eigen::Vector3d g;
            for (int k = 0; k < 3; ++k) {
                Eigen::Vector3d e = Eigen::Vector3d::Zero();
                e[k] = 1e-4;
                g[k] = shape.value(p + e) - shape.value(p - e);
            }
            v.points.normal(idx) = rgbd::to_vector(t.linear().transpose() * g.normalized());
        }
        rgbd::to_world_frame(v);
        views.push_back(std::move(v));
    }
    return views;
}

/// Points per 3-degree bin of direction from the ellipsoid's centre (azimuth, elevation).
std::map<std::pair<int, int>, double> bins(const PointCloud& c) {
    std::map<std::pair<int, int>, double> out;
    for (auto idx : c.points) {
        const Eigen::Vector3d u = rgbd::to_eigen(c.points.point(idx)).normalized();
        const int az = static_cast<int>(std::floor(std::atan2(u.x(), -u.z()) * 60.0 / M_PI));
        const int el = static_cast<int>(std::floor(std::asin(u.y()) * 60.0 / M_PI));
        out[{az, el}] += 1.0;
    }
    return out;
}

/// Median over bins well covered by both input views of merged / max(view a, view b): 1 when
/// the overlap keeps the density of one view, 2 for plain concatenation.
double overlap_density(const PointCloud& merged, const std::vector<PointCloud>& inputs) {
    const auto m = bins(merged), a = bins(inputs[0]), b = bins(inputs[1]);
    std::vector<double> all_a, all_b;
    for (const auto& [k, n] : a) all_a.push_back(n);
    for (const auto& [k, n] : b) all_b.push_back(n);
    std::sort(all_a.begin(), all_a.end());
    std::sort(all_b.begin(), all_b.end());
    const double ma = all_a[all_a.size() / 2], mb = all_b[all_b.size() / 2];
    std::vector<double> ratio;
    for (const auto& [k, n] : a) {
        const auto it = b.find(k);
        if (it == b.end() || n < 0.7 * ma || it->second < 0.7 * mb) continue;
        const auto mt = m.find(k);
        ratio.push_back((mt == m.end() ? 0.0 : mt->second) / std::max(n, it->second));
    }
    EXPECT_GT(ratio.size(), 20u) << "too few bins in the overlap";
    std::sort(ratio.begin(), ratio.end());
    return ratio[ratio.size() / 2];
}

TEST(DuplicateRemoval, OverlapKeepsTheDensityOfOneView) {
    const Rgb grey{120, 120, 120};
    auto plain = rgbd::sampling::merge_views(two_views(grey, grey));
    rgbd::registration::DuplicateReport rep;
    auto merged = rgbd::registration::merge_without_duplicates(two_views(grey, grey), {}, &rep);
    ASSERT_GT(rep.radius_m, 0);
    const auto inputs = two_views(grey, grey);
    const double plain_ratio = overlap_density(plain, inputs);
    const double ratio = overlap_density(merged, inputs);
    std::cout << "overlap density / one view's: plain " << plain_ratio << ", merged " << ratio
              << "; " << rep.duplicates << " duplicates of " << rep.input << "\n";
    EXPECT_GT(plain_ratio, 1.6);  // concatenation doubles the overlap
    EXPECT_GE(ratio, 0.8);
    EXPECT_LE(ratio, 1.25);
    EXPECT_GT(rep.duplicates, rep.input / 20);
    EXPECT_EQ(rep.replaced, 0u);
    EXPECT_EQ(rep.output, merged.size());
}

TEST(DuplicateRemoval, NoDoubleShellWhenColoursDisagree) {
    const Rgb a{200, 60, 60}, b{60, 60, 200};  // Delta E far above 15
    ASSERT_GT(rgbd::registration::delta_e76(a, b), 15.0);
    EXPECT_NEAR(rgbd::registration::delta_e76(a, a), 0.0, 1e-12);
    rgbd::registration::DuplicateReport rep;
    auto merged = rgbd::registration::merge_without_duplicates(two_views(a, b), {}, &rep);
    EXPECT_GT(rep.replaced, 0u);
    EXPECT_EQ(rep.duplicates, 0u);
    // No pair closer than 0.5 spacing with different colours.
    std::vector<Eigen::Vector3d> xyz;
    for (auto idx : merged.points) xyz.push_back(rgbd::to_eigen(merged.points.point(idx)));
    const rgbd::internal::KdTree tree(xyz);
    const auto colours = merged.colors();
    std::vector<std::pair<std::uint32_t, double>> nb;
    std::size_t i = 0, shells = 0;
    for (auto idx : merged.points) {
        tree.radius(xyz[i],
                    0.5 * rep.radius_m / rgbd::registration::DuplicateOptions{}.radius_spacing, nb);
        for (const auto& [j, d2] : nb) {
            auto jdx = *(merged.points.begin() + j);
            if (rgbd::registration::delta_e76(colours.get(idx), colours.get(jdx)) > 15) ++shells;
        }
        ++i;
    }
    EXPECT_EQ(shells, 0u);
}

TEST(DuplicateRemoval, BadInput) {
    auto views = two_views({1, 2, 3}, {1, 2, 3});
    rgbd::registration::DuplicateOptions bad;
    bad.radius_spacing = 0;
    EXPECT_THROW(rgbd::registration::merge_without_duplicates(std::move(views), bad),
                 rgbd::InputError);
    views = two_views({1, 2, 3}, {1, 2, 3});
    views[1].view.frame = rgbd::ViewFrame::kSensor;
    EXPECT_THROW(rgbd::registration::merge_without_duplicates(std::move(views), {}),
                 rgbd::InputError);
    EXPECT_THROW(rgbd::registration::merge_without_duplicates({}, {}), rgbd::InputError);
}

}  // namespace
