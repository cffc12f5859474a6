// Tests of capture folders (io/capture_folder.hpp): write -> read round trip, rig.json
// validation, image checks, and the read-only uva / TUM / Redwood layouts of shared/data.
#include "io/capture_folder.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <opencv2/imgcodecs.hpp>

#include "tests/support/input_error.hpp"
#include "tests/support/shared_data.hpp"
#include "tests/support/temp_dir.hpp"
#include "toolkit/error.hpp"
#include "toolkit/order_statistics.hpp"

namespace rgbd::io {
namespace {

namespace fs = std::filesystem;

fs::path temp_dir(const std::string& name) {
    return rgbd::test::fresh_temp_dir("capture_test", name, false);
}

using rgbd::test::expect_input_error;
using rgbd::test::shared_data;

/// The capture folder at `path` in the shared test data, expected to be read as `layout`.
Capture open_shared_capture(const std::string& path, const std::string& layout) {
    Capture cap = open_capture(shared_data(path));
    EXPECT_EQ(cap.layout, layout);
    return cap;
}

Pose test_pose(double angle, double tx) {
    Pose p = Pose::Identity();
    p.linear() =
        Eigen::AngleAxisd(angle, Eigen::Vector3d(0.2, 1, 0.1).normalized()).toRotationMatrix();
    p.translation() = Eigen::Vector3d(tx, -0.5 / 3.0, 1.25);
    return p;
}

Rig test_rig() {
    Rig rig;
    for (int s = 0; s < 2; ++s) {
        SensorSpec spec;
        spec.id = "k2-" + std::to_string(s);
        spec.model = "kinect_v2";
        spec.depth = {64, 48, 52.5, 52.5, 31.5, 23.5, {}};
        spec.color = {80, 60, 70.0, 70.0, 39.5, 29.5, {"brown", {0.01, -0.02}}};
        spec.depth_scale = s == 0 ? 1000.0 : 5000.0;
        spec.range_min_m = 0.5;
        spec.range_max_m = 4.5;
        spec.color_from_depth = Pose::Identity();
        spec.color_from_depth.translation() = Eigen::Vector3d(0.052, 0, 0);
        spec.world_from_depth = test_pose(0.7 * s, 0.1 / 3.0 * s);
        spec.noise_model = "kinect_v2";
        spec.clock_offset_ns = 1000 * s;
        spec.extra = {{"serial", "ABC" + std::to_string(s)}, {"noise", {{"sigma_mm", 1.5}}}};
        rig.sensors.push_back(spec);
    }
    rig.extra = {{"name", "test rig"}, {"created_by", {{"tool", "test"}}}};
    return rig;
}

cv::Mat test_depth(int w, int h, int seed) {
    cv::Mat d(h, w, CV_32FC1);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            d.at<float>(y, x) = 0.5f + 0.0137f * static_cast<float>((x * 7 + y * 3 + seed) % 200);
    d.at<float>(0, 0) = std::numeric_limits<float>::quiet_NaN();
    d.at<float>(1, 0) = 0.0f;
    d.at<float>(2, 0) = 100.0f;  // beyond uint16 at this scale -> invalid
    return d;
}

TEST(CaptureFolder, WriteThenReadRoundTrip) {
    const fs::path root = temp_dir("roundtrip");
    const Rig rig = test_rig();
    std::vector<cv::Mat> depths;
    {
        CaptureWriter writer(root, rig);
        for (int i = 0; i < 3; ++i) {
            for (const SensorSpec& s : rig.sensors) {
                cv::Mat depth = test_depth(64, 48, i);
                cv::Mat color(60, 80, CV_8UC3, cv::Scalar(10 * i, 100, 200));
                const std::optional<Pose> pose =
                    s.id == "k2-1" ? std::optional<Pose>(test_pose(0.1 * i, 0.01 * i))
                                   : std::nullopt;
                writer.add_frame(s.id, i, 1'000'000'000LL + 33'333'333LL * i, depth,
                                 i == 2 && s.id == "k2-0" ? cv::Mat() : color, pose);
                if (s.id == "k2-0") depths.push_back(depth);
            }
            writer.add_frameset(
                {i, 1'000'000'000LL + 33'333'333LL * i, 1200, {i, i == 1 ? -1 : i}});
        }
        EXPECT_THROW(writer.add_frame("nope", 0, 0, test_depth(64, 48, 0), cv::Mat()), InputError);
        EXPECT_THROW(writer.add_frame("k2-0", 9, 0, test_depth(32, 48, 0), cv::Mat()), InputError);
    }
    EXPECT_THROW(CaptureWriter(root, rig), IoError);  // not empty

    const Capture cap = open_capture(root);
    EXPECT_EQ(cap.layout, "rgbd-capture");
    ASSERT_EQ(cap.rig.sensors.size(), 2u);
    for (std::size_t s = 0; s < 2; ++s) {
        const SensorSpec& a = rig.sensors[s];
        const SensorSpec& b = cap.rig.sensors[s];
        EXPECT_EQ(a.id, b.id);
        EXPECT_EQ(a.model, b.model);
        EXPECT_TRUE(a.depth == b.depth);
        EXPECT_TRUE(a.color == b.color);
        EXPECT_EQ(a.color.distortion.coeffs, b.color.distortion.coeffs);
        EXPECT_EQ(a.depth_scale, b.depth_scale);
        EXPECT_EQ(a.range_min_m, b.range_min_m);
        EXPECT_EQ(a.range_max_m, b.range_max_m);
        EXPECT_TRUE(a.world_from_depth.matrix() == b.world_from_depth.matrix());
        EXPECT_TRUE(a.color_from_depth.matrix() == b.color_from_depth.matrix());
        EXPECT_EQ(a.noise_model, b.noise_model);
        EXPECT_EQ(a.clock_offset_ns, b.clock_offset_ns);
        EXPECT_EQ(b.extra.at("serial"), a.extra.at("serial"));
        EXPECT_EQ(b.extra.at("noise").at("sigma_mm"), 1.5);
    }
    EXPECT_EQ(cap.rig.extra.at("name"), "test rig");
    EXPECT_EQ(cap.rig.extra.at("created_by").at("tool"), "test");

    ASSERT_EQ(cap.framesets.size(), 3u);
    EXPECT_EQ(cap.framesets[1].frames, (std::vector<std::int64_t>{1, -1}));
    EXPECT_EQ(cap.framesets[2].spread_ns, 1200);
    EXPECT_EQ(cap.framesets[2].time_ns, 1'000'000'000LL + 2 * 33'333'333LL);

    ASSERT_EQ(cap.frames.at("k2-0").size(), 3u);
    ASSERT_EQ(cap.find_frame("k2-1", 2), std::optional<std::size_t>(2));
    EXPECT_FALSE(cap.find_frame("k2-1", 7).has_value());
    for (int i = 0; i < 3; ++i) {
        const RgbdFrame f = load_frame(cap, "k2-0", static_cast<std::size_t>(i));
        ASSERT_EQ(f.depth.type(), CV_32FC1);
        EXPECT_TRUE(std::isnan(f.depth.at<float>(0, 0)));
        EXPECT_TRUE(std::isnan(f.depth.at<float>(1, 0)));
        EXPECT_TRUE(std::isnan(f.depth.at<float>(2, 0)));
        double worst = 0;
        for (int y = 3; y < 48; ++y)
            for (int x = 0; x < 64; ++x)
                worst =
                    std::max(worst, std::abs(static_cast<double>(f.depth.at<float>(y, x)) -
                                             depths[static_cast<std::size_t>(i)].at<float>(y, x)));
        EXPECT_LE(worst, 0.5 / 1000.0 + 1e-6);
        EXPECT_EQ(f.color.empty(), i == 2);
        EXPECT_TRUE(f.has_pose);
        EXPECT_TRUE(f.world_from_sensor.matrix() == rig.sensors[0].world_from_depth.matrix());
        EXPECT_EQ(f.timestamp_ns, 1'000'000'000LL + 33'333'333LL * i);
        EXPECT_EQ(f.noise_model, "kinect_v2");
        EXPECT_FLOAT_EQ(f.range_max_m, 4.5f);
        EXPECT_EQ(f.frame_index, i);
    }
    const RgbdFrame g = load_frame(cap, "k2-1", 2);
    EXPECT_EQ(g.timestamp_ns, 1'000'000'000LL + 2 * 33'333'333LL - 1000);
    EXPECT_EQ(g.color.cols, 80);
    const cv::Vec3b px = g.color.at<cv::Vec3b>(5, 5);  // JPEG q95 of a flat colour: +-2
    EXPECT_LE(cv::norm(cv::Vec3d(px[0], px[1], px[2]) - cv::Vec3d(20, 100, 200), cv::NORM_INF),
              2.0);
    // Per-frame pose overrides the sensor's, to the last bit.
    EXPECT_TRUE(g.world_from_sensor.matrix() == test_pose(0.2, 0.02).matrix());
    fs::remove_all(root);
}

void write(const fs::path& file, const std::string& text) { std::ofstream(file) << text; }

std::string rig_error(const std::string& text) {
    const fs::path dir = temp_dir("rig");
    fs::create_directories(dir);
    write(dir / "rig.json", text);
    std::string message;
    try {
        read_rig(dir / "rig.json");
    } catch (const InputError& e) {
        message = e.what();
    }
    fs::remove_all(dir);
    return message;
}

TEST(CaptureFolder, EncodedFramesAreStoredBitForBit) {
    const fs::path dir = temp_dir("encoded");
    const Rig rig = test_rig();
    cv::Mat raw(48, 64, CV_16UC1);
    for (int i = 0; i < 48 * 64; ++i) raw.at<std::uint16_t>(i / 64, i % 64) = (i * 7919) % 65536;
    cv::Mat color(60, 80, CV_8UC3, cv::Scalar(10, 200, 30));
    std::vector<std::uint8_t> jpeg;
    cv::imencode(".jpg", color, jpeg, {cv::IMWRITE_JPEG_QUALITY, 70});
    {
        CaptureWriter w(dir, rig);
        w.add_encoded_frame("k2-1", 0, 123, raw, jpeg);
        w.add_encoded_frame("k2-1", 1, 456, raw, {});
        EXPECT_THROW(w.add_encoded_frame("k2-1", 2, 789, cv::Mat(48, 64, CV_32FC1), jpeg),
                     InputError);
        EXPECT_THROW(w.add_encoded_frame("k2-1", 2, 789, cv::Mat(4, 4, CV_16UC1), jpeg),
                     InputError);
    }
    const Capture cap = open_capture(dir);
    ASSERT_EQ(cap.frames.at("k2-1").size(), 2u);
    EXPECT_EQ(cap.frames.at("k2-1")[1].time_ns, 456);
    EXPECT_TRUE(cap.frames.at("k2-1")[1].color.empty());
    const cv::Mat back =
        cv::imread((dir / "k2-1" / cap.frames.at("k2-1")[0].depth).string(), cv::IMREAD_UNCHANGED);
    EXPECT_EQ(cv::norm(back, raw, cv::NORM_INF), 0.0);
    std::ifstream in(dir / "k2-1" / cap.frames.at("k2-1")[0].color, std::ios::binary);
    const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)), {});
    EXPECT_EQ(bytes, jpeg);
    fs::remove_all(dir);
}

TEST(CaptureFolder, BadRigJsonVariants) {
    const std::string good = R"({ "format": "rgbd-capture", "version": 1, "units": "m",
      "sensors": [ { "id": "k2-0", "model": "kinect_v2",
        "depth": { "width": 512, "height": 424, "fx": 365.5, "fy": 365.5, "cx": 256.0, "cy": 212.0,
                   "distortion": { "model": "none", "coeffs": [] } },
        "color": { "width": 1920, "height": 1080, "fx": 1081.37, "fy": 1081.37,
                   "cx": 959.5, "cy": 539.5,
                   "distortion": { "model": "none", "coeffs": [] } },
        "depth_scale": 1000.0, "range_m": [0.5, 4.5],
        "color_from_depth": [[1,0,0,0.052],[0,1,0,0],[0,0,1,0],[0,0,0,1]],
        "world_from_depth": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]],
        "noise": { "model": "kinect_v2" }, "clock": { "offset_ns": 0 } } ] })";
    EXPECT_EQ(rig_error(good), "");
    const auto variant = [&](const std::string& from, const std::string& to) {
        std::string t = good;
        const auto at = t.find(from);
        EXPECT_NE(at, std::string::npos) << from;
        t.replace(at, from.size(), to);
        return rig_error(t);
    };
    EXPECT_NE(variant(R"("depth_scale": 1000.0, )", "").find("missing key 'depth_scale'"),
              std::string::npos);
    EXPECT_NE(variant("[[1,0,0,0],[0,1,0,0]", "[[2,0,0,0],[0,1,0,0]").find("world_from_depth"),
              std::string::npos);
    EXPECT_NE(variant(R"("fx": 365.5)", R"("fx": -365.5)").find("focal"), std::string::npos);
    EXPECT_NE(variant(R"("version": 1)", R"("version": 2)").find("version"), std::string::npos);
    EXPECT_NE(variant(R"("units": "m")", R"("units": "mm")").find("units"), std::string::npos);
    EXPECT_NE(variant(R"("depth_scale": 1000.0)", R"("depth_scale": 0)").find("depth_scale"),
              std::string::npos);
    EXPECT_NE(variant("[0.5, 4.5]", "[4.5, 0.5]").find("range_m"), std::string::npos);
    EXPECT_NE(rig_error("{ this is not json").find("not valid JSON"), std::string::npos);
    const std::string twice =
        good.substr(0, good.rfind(']')) + ", " +
        good.substr(good.find("{ \"id\""), good.rfind(']') - good.find("{ \"id\"")) + "] }";
    EXPECT_NE(rig_error(twice).find("duplicate sensor id"), std::string::npos) << rig_error(twice);
    EXPECT_NE(rig_error(good).find("rig.json"), 0u);  // sanity: errors name the file (see above)
    EXPECT_NE(variant(R"("fx": 365.5)", R"("fx": -365.5)").find("rig.json"), std::string::npos);
}

TEST(CaptureFolder, MissingAndWrongSizedImagesAreNamed) {
    const fs::path root = temp_dir("images");
    Rig rig = test_rig();
    rig.sensors.resize(1);
    {
        CaptureWriter writer(root, rig);
        writer.add_frame("k2-0", 0, 0, test_depth(64, 48, 0), cv::Mat(60, 80, CV_8UC3));
        writer.add_frame("k2-0", 1, 1, test_depth(64, 48, 1), cv::Mat(60, 80, CV_8UC3));
        writer.add_frame("k2-0", 2, 2, test_depth(64, 48, 2), cv::Mat(60, 80, CV_8UC3));
    }
    fs::remove(root / "k2-0" / "depth" / "000001.png");
    cv::imwrite((root / "k2-0" / "color" / "000002.jpg").string(), cv::Mat(30, 40, CV_8UC3));
    const Capture cap = open_capture(root);
    EXPECT_NO_THROW(load_frame(cap, "k2-0", 0));
    expect_input_error([&] { load_frame(cap, "k2-0", 1); }, {"000001.png", "missing"});
    expect_input_error([&] { load_frame(cap, "k2-0", 2); }, {"000002.jpg", "40x30", "80x60"});
    EXPECT_THROW(load_frame(cap, "k2-0", 5), InputError);
    EXPECT_THROW(load_frame(cap, "other", 0), InputError);
    fs::remove_all(root);
}

TEST(CaptureFolder, UnknownFolderIsAnError) {
    const fs::path root = temp_dir("unknown");
    fs::create_directories(root);
    write(root / "readme.txt", "hello");
    expect_input_error([&] { open_capture(root); }, {"not a capture folder", root.string()});
    EXPECT_THROW(open_capture(root / "missing"), InputError);
    fs::remove_all(root);
}

TEST(CaptureFolder, AtomicHelpersLeaveNoTemporaryFiles) {
    const fs::path root = temp_dir("atomic");
    fs::create_directories(root);
    write_text_atomic(root / "a.txt", "x");
    write_image_atomic(root / "b.png", cv::Mat(4, 4, CV_16UC1, cv::Scalar(7)));
    EXPECT_THROW(write_image_atomic(root / "c.png", cv::Mat()), InputError);
    EXPECT_THROW(write_text_atomic(root / "no" / "d.txt", "x"), IoError);
    EXPECT_EQ(std::distance(fs::directory_iterator(root), fs::directory_iterator()), 2);
    EXPECT_EQ(cv::imread((root / "b.png").string(), cv::IMREAD_UNCHANGED).at<std::uint16_t>(3, 3),
              7);
    fs::remove_all(root);
}

TEST(CaptureFolder, UvaLayout) {
    RGBD_SKIP_WITHOUT_SHARED_DATA();
    const Capture cap = open_shared_capture("multiview/uva_cv2_person_kinect1", "uva");
    ASSERT_EQ(cap.frames.at("camera").size(), 50u);
    const SensorSpec& s = cap.rig.sensor("camera");
    EXPECT_EQ(s.depth.width, 640);
    EXPECT_EQ(s.depth.fx, 525.0);
    EXPECT_EQ(s.depth.cx, 320.0);
    EXPECT_EQ(cap.frames.at("camera")[1].index, 2);
    const RgbdFrame f = load_frame(cap, "camera", 0);
    EXPECT_TRUE(f.has_pose);
    EXPECT_NEAR(f.world_from_sensor.translation().x(), 0.626666665, 1e-6);
    ASSERT_FALSE(f.mask.empty());
    const double person = cv::countNonZero(f.mask);
    EXPECT_GT(person, 10000);
    EXPECT_LT(person, 640 * 480 / 2);
    // Masked depth lies on the person, 0.8-1.0 m.
    std::vector<float> z;
    for (int y = 0; y < 480; ++y)
        for (int x = 0; x < 640; ++x)
            if (f.mask.at<std::uint8_t>(y, x) && std::isfinite(f.depth.at<float>(y, x)))
                z.push_back(f.depth.at<float>(y, x));
    ASSERT_GT(z.size(), 5000u);
    const float median = upper_median(z);
    EXPECT_GT(median, 0.75f);
    EXPECT_LT(median, 1.05f);
    EXPECT_EQ(f.color.size(), cv::Size(640, 480));
    EXPECT_EQ(load_frame(cap, "camera", 25).timestamp_ns, 50 * 33'333'333LL);
    const double turn =
        rotation_error_deg(load_frame(cap, "camera", 25).world_from_sensor, f.world_from_sensor);
    EXPECT_GT(turn, 150.0);  // the person turned about 180 degrees by frame 50
}

TEST(CaptureFolder, TumSample) {
    RGBD_SKIP_WITHOUT_SHARED_DATA();
    const Capture cap = open_shared_capture("rgbd/open3d_tum_nyu_sun_samples", "tum");
    ASSERT_EQ(cap.frames.at("camera").size(), 1u);
    EXPECT_EQ(cap.rig.sensor("camera").depth_scale, 5000.0);
    const RgbdFrame f = load_frame(cap, "camera", 0);
    EXPECT_FALSE(f.has_pose);
    std::vector<float> z;
    for (int y = 0; y < f.depth.rows; ++y)
        for (int x = 0; x < f.depth.cols; ++x)
            if (std::isfinite(f.depth.at<float>(y, x))) z.push_back(f.depth.at<float>(y, x));
    ASSERT_GT(z.size(), 100000u);
    EXPECT_NEAR(upper_median(z), 2.4, 0.4);  // README: median about 2.4 m
    EXPECT_EQ(f.color.type(), CV_8UC3);
}

TEST(CaptureFolder, TumListFiles) {
    const fs::path root = temp_dir("tum");
    fs::create_directories(root / "rgb");
    fs::create_directories(root / "depth");
    cv::Mat d(480, 640, CV_16UC1, cv::Scalar(5000));
    cv::imwrite((root / "depth" / "1.000000.png").string(), d);
    cv::imwrite((root / "depth" / "1.033000.png").string(), d * 2);
    cv::imwrite((root / "rgb" / "1.010000.png").string(), cv::Mat(480, 640, CV_8UC3));
    write(root / "depth.txt",
          "# depth maps\n1.000000 depth/1.000000.png\n1.033000 depth/1.033000.png\n");
    write(root / "rgb.txt", "# colour\n1.010000 rgb/1.010000.png\n");
    write(root / "groundtruth.txt", "# t tx ty tz qx qy qz qw\n1.001 1 2 3 0 0 0 1\n");
    const Capture cap = open_capture(root);
    EXPECT_EQ(cap.layout, "tum");
    const auto& frames = cap.frames.at("camera");
    ASSERT_EQ(frames.size(), 2u);
    EXPECT_EQ(frames[0].time_ns, 1'000'000'000LL);
    EXPECT_FALSE(frames[0].color.empty());  // 10 ms away
    EXPECT_TRUE(frames[1].color.empty());   // 23 ms away: not associated
    const RgbdFrame f = load_frame(cap, "camera", 1);
    EXPECT_FLOAT_EQ(f.depth.at<float>(5, 5), 2.0f);
    EXPECT_TRUE(load_frame(cap, "camera", 0).has_pose);
    EXPECT_FALSE(f.has_pose);
    fs::remove_all(root);
}

TEST(CaptureFolder, RedwoodLayoutWithCleanDepth) {
    RGBD_SKIP_WITHOUT_SHARED_DATA();
    const Capture cap = open_shared_capture("rgbd/open3d_livingroom1_augmented_iclnuim", "redwood");
    ASSERT_EQ(cap.frames.at("camera").size(), 5u);
    ASSERT_EQ(cap.frames.at("clean").size(), 5u);
    EXPECT_EQ(cap.rig.sensor("camera").depth.cx, 319.5);
    const RgbdFrame noisy = load_frame(cap, "camera", 0);
    const RgbdFrame clean = load_frame(cap, "clean", 0);
    EXPECT_TRUE(noisy.has_pose);
    EXPECT_NEAR(noisy.world_from_sensor.translation().z(), 2.1264800183565487, 1e-12);
    EXPECT_TRUE(clean.world_from_sensor.matrix() == noisy.world_from_sensor.matrix());
    EXPECT_FALSE(noisy.color.empty());
    double sum = 0;
    std::size_t n = 0;
    for (int y = 0; y < 480; ++y)
        for (int x = 0; x < 640; ++x) {
            const float a = noisy.depth.at<float>(y, x), b = clean.depth.at<float>(y, x);
            if (std::isfinite(a) && std::isfinite(b)) {
                sum += std::abs(a - b);
                ++n;
            }
        }
    ASSERT_GT(n, 100000u);
    EXPECT_NEAR(sum / static_cast<double>(n), 0.0147, 0.006);  // README: 14.7 mm
}

}  // namespace
}  // namespace rgbd::io
