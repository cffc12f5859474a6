// Tests of the APC vision toolbox layout (io/capture_foreign.cpp, open_apc) on
// shared/data/multiview/apc_realsense_f200_shelf: 15 views of a shelf bin from a RealSense F200
// on a robot arm, depth registered to the colour camera with its bits rotated right by 3.
// The bit rotation and the camera-to-world pose convention are checked together by the views'
// agreement in the world; the registration to the colour grid by the object masks.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nanoflann.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "io/capture_folder.hpp"
#include "tests/support/input_error.hpp"
#include "tests/support/shared_data.hpp"
#include "tests/support/temp_dir.hpp"
#include "toolkit/error.hpp"
#include "toolkit/order_statistics.hpp"

namespace rgbd::io {
namespace {

namespace fs = std::filesystem;
using rgbd::test::shared_data;

const fs::path kApc = shared_data("multiview/apc_realsense_f200_shelf");
const char* const kObjects[] = {"creativity_chenille_stems", "i_am_a_bunny_book",
                                "kleenex_tissue_box", "laugh_out_loud_joke_book"};

std::string frame_name(int index) {
    char name[32];
    std::snprintf(name, sizeof(name), "frame-%06d", index);
    return name;
}

std::vector<float> valid_depths(const cv::Mat& depth) {
    std::vector<float> z;
    for (int y = 0; y < depth.rows; ++y)
        for (int x = 0; x < depth.cols; ++x)
            if (std::isfinite(depth.at<float>(y, x))) z.push_back(depth.at<float>(y, x));
    return z;
}

/// Every `step`-th pixel with depth in [0.2, 1.2] m (the F200's range), back-projected with
/// the frame's depth intrinsics and moved to the world with `world_from_camera`.
std::vector<Eigen::Vector3d> world_points(const cv::Mat& depth, const PinholeIntrinsics& k,
                                          const Pose& world_from_camera, int step) {
    std::vector<Eigen::Vector3d> out;
    for (int y = 0; y < depth.rows; y += step)
        for (int x = 0; x < depth.cols; x += step) {
            const double z = depth.at<float>(y, x);
            if (!(z >= 0.2 && z <= 1.2)) continue;
            out.push_back(world_from_camera *
                          Eigen::Vector3d((x - k.cx) / k.fx * z, (y - k.cy) / k.fy * z, z));
        }
    return out;
}

struct Cloud {
    const std::vector<Eigen::Vector3d>* points;
    std::size_t kdtree_get_point_count() const { return points->size(); }
    double kdtree_get_pt(std::size_t i, std::size_t d) const { return (*points)[i][d]; }
    template <class Box>
    bool kdtree_get_bbox(Box&) const {
        return false;
    }
};
using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, Cloud>, Cloud,
                                                 3, std::uint32_t>;

/// How well `a` lies on `b`: the median nearest-neighbour distance of all of a's points, and
/// over the overlap (a's points with a neighbour in b within 5 cm) with its share of a.
struct Agreement {
    double median_m = 0;
    double overlap_median_m = 0;
    double overlap = 0;
};

Agreement agreement(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b) {
    const Cloud cloud{&b};
    Tree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16));
    tree.buildIndex();
    std::vector<double> all, near;
    for (const Eigen::Vector3d& p : a) {
        std::uint32_t index = 0;
        double sq = 0;
        nanoflann::KNNResultSet<double, std::uint32_t> result(1);
        result.init(&index, &sq);
        tree.findNeighbors(result, p.data(), nanoflann::SearchParams());
        all.push_back(std::sqrt(sq));
        if (all.back() < 0.05) near.push_back(all.back());
    }
    Agreement r;
    if (all.empty()) return r;
    r.median_m = upper_median(all);
    r.overlap = static_cast<double>(near.size()) / static_cast<double>(all.size());
    r.overlap_median_m = near.empty() ? 1.0 : upper_median(near);
    return r;
}

Agreement frames_agreement(const Capture& cap, std::size_t a, std::size_t b,
                           bool invert_poses = false) {
    const RgbdFrame fa = load_frame(cap, "camera", a), fb = load_frame(cap, "camera", b);
    const auto pose = [&](const RgbdFrame& f) {
        return invert_poses ? Pose(f.world_from_sensor.inverse()) : f.world_from_sensor;
    };
    return agreement(world_points(fa.depth, fa.depth_intrinsics, pose(fa), 2),
                     world_points(fb.depth, fb.depth_intrinsics, pose(fb), 1));
}

TEST(CaptureApc, DecodeDepthUndoesTheRotation) {
    cv::Mat stored(2, 3, CV_16UC1);
    const std::uint16_t depth[6] = {0, 1, 5500, 15000, 65535, 8};
    for (int k = 0; k < 6; ++k)  // the toolbox stores the depth rotated left by 3
        stored.at<std::uint16_t>(k / 3, k % 3) =
            static_cast<std::uint16_t>((depth[k] << 3) | (depth[k] >> 13));
    cv::Mat plain = stored.clone();
    decode_depth(plain, DepthEncoding::kPlain);
    EXPECT_EQ(cv::countNonZero(plain != stored), 0);
    decode_depth(stored, DepthEncoding::kApcRotated3);
    for (int k = 0; k < 6; ++k) EXPECT_EQ(stored.at<std::uint16_t>(k / 3, k % 3), depth[k]);
    cv::Mat wrong(2, 2, CV_8UC1);
    EXPECT_THROW(decode_depth(wrong, DepthEncoding::kApcRotated3), InputError);
    EXPECT_EQ(to_string(DepthEncoding::kApcRotated3), "apc_rotated3");
}

TEST(CaptureApc, OpensOneSensorFifteenPosedFrames) {
    RGBD_SKIP_WITHOUT(kApc);
    const Capture cap = open_capture(kApc);
    EXPECT_EQ(cap.layout, "apc");
    ASSERT_EQ(cap.rig.sensors.size(), 1u);
    const SensorSpec& s = cap.rig.sensor("camera");
    EXPECT_EQ(s.model, "realsense_f200");
    EXPECT_EQ(s.noise_model, "sr300");
    EXPECT_EQ(s.depth_encoding, DepthEncoding::kApcRotated3);
    EXPECT_EQ(s.depth_scale, 10000.0);
    EXPECT_EQ(s.depth.width, 640);
    EXPECT_EQ(s.depth.height, 480);
    EXPECT_DOUBLE_EQ(s.depth.fx, 615.195190);  // the colour intrinsics: depth is registered
    EXPECT_DOUBLE_EQ(s.depth.cy, 247.519196);
    EXPECT_DOUBLE_EQ(s.color.cx, s.depth.cx);
    EXPECT_TRUE(s.color_from_depth.isApprox(Pose::Identity()));
    EXPECT_DOUBLE_EQ(s.extra.at("raw_depth").at("intrinsics").at("fx").get<double>(), 477.584259);
    EXPECT_EQ(cap.rig.extra.at("apc").at("objects").size(), 4u);
    EXPECT_EQ(cap.rig.extra.at("apc").at("bin_id"), "B");
    EXPECT_DOUBLE_EQ(cap.rig.extra.at("apc").at("world_from_bin")[2][3].get<double>(), 1.03730530);
    const auto& frames = cap.frames.at("camera");
    ASSERT_EQ(frames.size(), 15u);
    for (std::size_t k = 0; k < frames.size(); ++k) {
        EXPECT_EQ(frames[k].index, static_cast<std::int64_t>(k));
        EXPECT_EQ(frames[k].time_ns, static_cast<std::int64_t>(k) * 1'000'000'000);
        EXPECT_TRUE(frames[k].world_from_depth.has_value());
        EXPECT_FALSE(frames[k].color.empty());
    }
    // Frame 7's camera-to-world translation, as written in cam.info.txt.
    EXPECT_NEAR(frames[7].world_from_depth->translation().x(), 1.14220022, 1e-8);
    EXPECT_NEAR(frames[7].world_from_depth->translation().z(), 1.21843008, 1e-8);

    const RgbdFrame f = load_frame(cap, "camera", 0);
    EXPECT_TRUE(f.has_pose);
    EXPECT_EQ(f.color.size(), cv::Size(640, 480));
    std::vector<float> z = valid_depths(f.depth);
    ASSERT_GT(z.size(), 70000u);  // 81376: the registered depth is a lattice with holes
    // README: frame 0 spans 0.09-1.50 m, median 0.55 m.
    EXPECT_NEAR(upper_median(z), 0.55, 0.02);
    EXPECT_NEAR(*std::min_element(z.begin(), z.end()), 0.09, 0.01);
    EXPECT_NEAR(*std::max_element(z.begin(), z.end()), 1.50, 0.02);
    // Read without undoing the rotation, the same file is garbage: most values are beyond
    // the 1.2 m the F200 reaches (any depth >= 0.8 mm with low bits set lands above 0.8 m).
    const cv::Mat stored =
        cv::imread((kApc / "frame-000000.depth.png").string(), cv::IMREAD_UNCHANGED);
    std::size_t beyond = 0, nonzero = 0;
    for (auto it = stored.begin<std::uint16_t>(); it != stored.end<std::uint16_t>(); ++it) {
        nonzero += *it != 0;
        beyond += *it / 10000.0 > 1.5;
    }
    EXPECT_GT(static_cast<double>(beyond), 0.5 * static_cast<double>(nonzero));
}

// Back-projected with the arm's camera-to-world poses, the views lie on each other. This checks
// the bit rotation and the pose convention at once. Measured (every 2nd pixel of the first view
// against all of the second, 0.2-1.2 m; overlap = points with a neighbour within 5 cm):
//   frames 0 and 7: median NN 4.5 mm over the overlap, 5.9 mm over all, 81 % overlap;
//   neighbouring frames: median NN 2.3-3.9 mm over the overlap, >= 93 % overlap;
//   poses inverted (read as world-to-camera): median NN 0.45 m, no overlap.
TEST(CaptureApc, ViewsAgreeInTheWorldWithTheArmPoses) {
    RGBD_SKIP_WITHOUT(kApc);
    const Capture cap = open_capture(kApc);
    const Agreement far = frames_agreement(cap, 0, 7);
    EXPECT_LT(far.overlap_median_m, 0.01);
    EXPECT_LT(far.median_m, 0.012);
    EXPECT_GT(far.overlap, 0.6);
    for (std::size_t k = 0; k + 1 < 15; ++k) {
        const Agreement a = frames_agreement(cap, k, k + 1);
        EXPECT_LT(a.overlap_median_m, 0.008) << "frames " << k << ", " << k + 1;
        EXPECT_GT(a.overlap, 0.8) << "frames " << k << ", " << k + 1;
    }
    const Agreement inverted = frames_agreement(cap, 0, 7, /*invert_poses=*/true);
    EXPECT_GT(inverted.median_m, 0.2);
    EXPECT_LT(inverted.overlap, 0.1);
}

// The toolbox's object masks (soft, 0-255 per colour pixel) are on the colour grid; where a
// confident mask marks an object, the registered depth has returns. The registered depth is
// forward-mapped from the wider depth camera (fx 478 px) onto the colour grid (fx 615 px), so
// it is a lattice with holes: 26-29 % of all pixels are valid, 42-55 % of the masked ones. The
// check therefore counts a pixel as having depth when one lies in its 3x3 neighbourhood.
// Measured over the 15 frames, masks with a peak >= 200 and their pixels >= peak / 2: 0.70-0.99
// per mask, 0.90 pooled; the whole image 0.54.
TEST(CaptureApc, MaskedObjectPixelsHaveDepth) {
    RGBD_SKIP_WITHOUT(kApc);
    const Capture cap = open_capture(kApc);
    std::size_t pooled_masked = 0, pooled_valid = 0, image_valid = 0, image = 0;
    for (std::size_t k = 0; k < 15; ++k) {
        const RgbdFrame f = load_frame(cap, "camera", k);
        cv::Mat near_depth(f.depth.size(), CV_8UC1, cv::Scalar(0));  // a return within 3x3
        for (int y = 0; y < f.depth.rows; ++y)
            for (int x = 0; x < f.depth.cols; ++x)
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx) {
                        const int yy = std::clamp(y + dy, 0, f.depth.rows - 1);
                        const int xx = std::clamp(x + dx, 0, f.depth.cols - 1);
                        if (std::isfinite(f.depth.at<float>(yy, xx)))
                            near_depth.at<std::uint8_t>(y, x) = 1;
                    }
        image_valid += static_cast<std::size_t>(cv::countNonZero(near_depth));
        image += near_depth.total();
        for (const char* object : kObjects) {
            const fs::path file =
                kApc / "masks" / (frame_name(static_cast<int>(k)) + "." + object + ".mask.png");
            const cv::Mat mask = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
            ASSERT_EQ(mask.size(), f.depth.size()) << file;
            double low = 0, peak = 0;
            cv::minMaxLoc(mask, &low, &peak);
            if (peak < 200) continue;  // the toolbox is not sure the object is in view
            std::size_t masked = 0, valid = 0;
            for (int y = 0; y < mask.rows; ++y)
                for (int x = 0; x < mask.cols; ++x)
                    if (mask.at<std::uint8_t>(y, x) >= peak / 2) {
                        ++masked;
                        valid += near_depth.at<std::uint8_t>(y, x);
                    }
            EXPECT_GT(static_cast<double>(valid) / static_cast<double>(masked), 0.6)
                << file << ": " << valid << " of " << masked;
            pooled_masked += masked;
            pooled_valid += valid;
        }
    }
    ASSERT_GT(pooled_masked, 100000u);
    const double pooled = static_cast<double>(pooled_valid) / static_cast<double>(pooled_masked);
    const double whole = static_cast<double>(image_valid) / static_cast<double>(image);
    EXPECT_GT(pooled, 0.85);
    EXPECT_GT(pooled, whole + 0.2);
}

/// A copy of the layout in a temporary folder: the PNGs symlinked, cam.info.txt `info`.
fs::path apc_copy(const std::string& name, const std::string& info) {
    const fs::path root = rgbd::test::fresh_temp_dir("capture_apc", name);
    for (const auto& e : fs::directory_iterator(kApc))
        if (e.path().extension() == ".png")
            fs::create_symlink(e.path(), root / e.path().filename());
    std::ofstream(root / "cam.info.txt") << info;
    return root;
}

std::string original_info() {
    std::ifstream in(kApc / "cam.info.txt");
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

TEST(CaptureApc, CamInfoWithSpacesInsteadOfTabsReadsTheSame) {
    RGBD_SKIP_WITHOUT(kApc);
    std::string info = original_info();
    std::replace(info.begin(), info.end(), '\t', ' ');
    const fs::path root = apc_copy("spaces", info);
    const Capture a = open_capture(kApc), b = open_capture(root);
    for (std::size_t k = 0; k < 15; ++k)
        EXPECT_TRUE(a.frames.at("camera")[k].world_from_depth->isApprox(
            *b.frames.at("camera")[k].world_from_depth, 1e-15));
    fs::remove_all(root);
}

TEST(CaptureApc, TruncatedOrIncompleteCamInfoNamesTheBlock) {
    RGBD_SKIP_WITHOUT(kApc);
    const std::string info = original_info();
    // Cut the file after the third row of frame 7's pose.
    const std::size_t title = info.find("for frame-000007");
    ASSERT_NE(title, std::string::npos);
    std::size_t cut = title;
    for (int line = 0; line < 4; ++line) cut = info.find('\n', cut) + 1;
    const fs::path root = apc_copy("truncated", info.substr(0, cut));
    const std::string message = rgbd::test::input_error_message([&] { open_capture(root); });
    EXPECT_NE(message.find((root / "cam.info.txt").string()), std::string::npos) << message;
    EXPECT_NE(message.find("pose of frame-000007 has 3 rows (expected 4)"), std::string::npos)
        << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;

    // A missing block, a short row.
    std::string no_color = info;
    no_color.replace(no_color.find("# Color camera"), 8, "# Colour");
    std::ofstream(root / "cam.info.txt") << no_color;
    rgbd::test::expect_input_error([&] { open_capture(root); },
                                   {"cam.info.txt", "no colour intrinsics"});
    std::string short_row = info;
    short_row.replace(short_row.find("4.27287677e-03"), 14, "");
    std::ofstream(root / "cam.info.txt") << short_row;
    rgbd::test::expect_input_error(
        [&] { open_capture(root); },
        {"cam.info.txt", "depth-to-colour extrinsic: row 3 has 3 numbers (expected 4)"});
    fs::remove_all(root);
}

TEST(CaptureApc, DepthImageOfTheWrongSizeNamesTheFile) {
    RGBD_SKIP_WITHOUT(kApc);
    const fs::path root = apc_copy("wrong_size", original_info());
    const fs::path bad = root / "frame-000003.depth.png";
    fs::remove(bad);
    cv::imwrite(bad.string(), cv::Mat(240, 320, CV_16UC1, cv::Scalar(4400)));
    const Capture cap = open_capture(root);
    EXPECT_NO_THROW(load_frame(cap, "camera", 2));
    rgbd::test::expect_input_error([&] { load_frame(cap, "camera", 3); },
                                   {bad.string(), "320x240"});
    fs::remove_all(root);
}

}  // namespace
}  // namespace rgbd::io
