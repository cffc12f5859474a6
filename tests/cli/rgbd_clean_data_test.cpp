// rgbd-clean on a real raw sensor cloud (issue 3 "done when"): the frame-0 PCD of the UvA
// person sequence (Kinect v1 class, 68,742 points, ascii x y z rgb, camera frame) read as a
// plain cloud file, one unorganised view. It holds 1,495 gross outliers (saturated depth
// reprojected to z = 65.5 m, |x| and |y| up to 28 m); the person stands at z = 0.81-0.99 m
// and a few background points lie at z = 2.5-2.7 m. Every gross outlier (z > 5 m, |x| > 3 m
// or |y| > 3 m) must go and >= 95% of the person (z < 1.5 m) must stay, with the default
// method for a cloud without a pixel grid and with --density. Skips without ../shared/data.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "io/mesh_io.hpp"
#include "tests/support/shared_data.hpp"
#include "tests/support/tool_runner.hpp"

namespace fs = std::filesystem;

namespace {

const fs::path kPcd = rgbd::test::shared_data("multiview/uva_cv2_person_kinect1/0000000000.pcd");

fs::path temp_root() {
    static const fs::path root = rgbd::test::scratch_dir("rgbd_clean_data_test");
    return root;
}

struct Counts {
    std::size_t total = 0, gross = 0, person = 0;
};

Counts count(const fs::path& file) {
    const rgbd::PointCloud cloud = rgbd::io::read_point_cloud(file);
    Counts c;
    for (auto idx : cloud.points) {
        const auto& p = cloud.points.point(idx);
        ++c.total;
        if (p.z() > 5.0 || std::abs(p.x()) > 3.0 || std::abs(p.y()) > 3.0)
            ++c.gross;
        else if (p.z() < 1.5)
            ++c.person;
    }
    return c;
}

void check_method(const std::string& method, const std::string& out) {
    RGBD_SKIP_WITHOUT(kPcd);
    const Counts before = count(kPcd);
    ASSERT_EQ(before.total, 68742u);
    ASSERT_EQ(before.gross, 1495u);
    const rgbd::test::Outcome r = rgbd::test::run_in(
        temp_root(), "$BIN/rgbd-clean " + method + " " + kPcd.string() + " -q > " + out);
    ASSERT_EQ(r.code, 0) << r.err;
    const Counts after = count(temp_root() / out);
    EXPECT_EQ(after.gross, 0u) << method;
    EXPECT_GE(double(after.person), 0.95 * double(before.person))
        << method << ": kept " << after.person << " of " << before.person << " person points";
}

}  // namespace

TEST(RgbdCleanData, RawPersonPcdDefaultMethodRemovesGrossOutliers) {
    check_method("", "default.ply");
}

TEST(RgbdCleanData, RawPersonPcdDensityRemovesGrossOutliers) {
    check_method("--density", "density.ply");
}

TEST(RgbdCleanData, RawPersonPcdDistanceSuggestsDensity) {
    RGBD_SKIP_WITHOUT(kPcd);
    const rgbd::test::Outcome r =
        rgbd::test::run_in(temp_root(), "$BIN/rgbd-clean --distance " + kPcd.string() + " -q");
    EXPECT_NE(r.code, 0);
    EXPECT_NE(r.err.find("--density"), std::string::npos) << r.err;
}
