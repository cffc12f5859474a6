// Tests of the playback sensor (sensors/playback/playback_sensor.hpp) and the registry:
// depth delivered bit for bit, JPEG colour passed through unchanged, recorded rate, loop,
// frame limit, alignment of several sensors on the clock grid, and errors naming the problem.
#include "sensors/playback/playback_sensor.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "sensors/registry.hpp"
#include "sensors/synthetic/synthetic_sensor.hpp"
#include "tests/support/input_error.hpp"
#include "tests/support/pinhole.hpp"
#include "toolkit/error.hpp"

namespace rgbd::sensors {
namespace {

using rgbd::test::expect_input_error;

namespace fs = std::filesystem;

io::SensorSpec small_spec(const std::string& id) {
    io::SensorSpec s;
    s.id = id;
    s.model = "test";
    s.depth = test::centred_pinhole(8, 6, 10);
    s.color = s.depth;
    return s;
}

// Two sensors, 4 frames at 50 Hz, sensor b recorded 5 ms after a, clock offsets differ.
fs::path make_capture() {
    const fs::path root =
        fs::temp_directory_path() / ("rgbd_playback_test_" + std::to_string(::getpid()));
    fs::remove_all(root);
    io::Rig rig;
    rig.sensors = {small_spec("a"), small_spec("b")};
    rig.sensors[0].clock_offset_ns = 1'000'000'000;
    rig.sensors[1].clock_offset_ns = -7'000'000;
    io::CaptureWriter w(root, rig);
    for (int f = 0; f < 4; ++f)
        for (int s = 0; s < 2; ++s) {
            cv::Mat depth(6, 8, CV_16UC1);
            for (int i = 0; i < 48; ++i)
                depth.at<std::uint16_t>(i / 8, i % 8) =
                    (f * 100 + s * 10 + i) % 7 == 0 ? 0 : 1000 + f * 100 + s * 10 + i;
            cv::Mat color(6, 8, CV_8UC3, cv::Scalar(f * 10, s * 50, 200));
            std::vector<std::uint8_t> jpeg;
            cv::imencode(".jpg", color, jpeg);
            const std::int64_t hub = 5'000'000'000 + f * 20'000'000 + s * 5'000'000;
            w.add_encoded_frame(rig.sensors[s].id, f, hub + rig.sensors[s].clock_offset_ns, depth,
                                jpeg);
        }
    return root;
}

/// Tests on the capture of make_capture(), removed afterwards.
class PlaybackOfACapture : public ::testing::Test {
protected:
    ~PlaybackOfACapture() override { fs::remove_all(root); }
    const fs::path root = make_capture();
};

TEST_F(PlaybackOfACapture, DeliversStoredDepthAndJpegUnchanged) {
    PlaybackOptions o;
    o.realtime = false;
    PlaybackSensor sensor(root, "b", o);
    EXPECT_EQ(sensor.recording_size(), 4u);
    EXPECT_NEAR(sensor.frame_rate_hz(), 50.0, 1e-9);
    const io::Capture cap = io::open_capture(root);
    SensorFrame frame;
    for (int f = 0; f < 4; ++f) {
        ASSERT_TRUE(sensor.next(frame));
        const cv::Mat stored =
            cv::imread((root / "b" / cap.frames.at("b")[f].depth).string(), cv::IMREAD_UNCHANGED);
        EXPECT_EQ(cv::norm(stored, frame.depth, cv::NORM_INF), 0.0);
        std::ifstream in(root / "b" / cap.frames.at("b")[f].color, std::ios::binary);
        const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)), {});
        EXPECT_EQ(frame.color_jpeg, bytes);
        EXPECT_TRUE(frame.color.empty());
        EXPECT_EQ(frame.index, f);
        EXPECT_EQ(frame.source_position, f);
    }
    EXPECT_FALSE(sensor.next(frame));
}

TEST_F(PlaybackOfACapture, LoopsAndStopsAtTheLimit) {
    PlaybackOptions o;
    o.realtime = false;
    o.loop = true;
    o.max_frames = 10;
    PlaybackSensor sensor(root, "a", o);
    EXPECT_EQ(sensor.loop_ns(), 100'000'000);  // span 65 ms + period, rounded up to periods
    SensorFrame frame;
    std::int64_t first_device = 0;
    for (int f = 0; f < 10; ++f) {
        ASSERT_TRUE(sensor.next(frame));
        EXPECT_EQ(frame.source_position, f % 4);
        if (f == 0) first_device = frame.device_ns;
        if (f == 4) {
            EXPECT_EQ(frame.device_ns - first_device, 100'000'000);
        }
    }
    EXPECT_FALSE(sensor.next(frame));
}

TEST_F(PlaybackOfACapture, RealTimeSensorsOfOneCaptureKeepTheirRecordedPhase) {
    PlaybackOptions o;
    o.loop = true;
    o.max_frames = 3;
    PlaybackSensor a(root, "a", o);
    PlaybackSensor b(root, "b", o);
    SensorFrame fa, fb;
    ASSERT_TRUE(a.next(fa));
    ASSERT_TRUE(b.next(fb));
    // Same grid: b's instants are 5 ms after a's (the recorded phase), modulo the loop.
    const std::int64_t d =
        ((fb.capture_ns - fa.capture_ns) % a.loop_ns() + a.loop_ns()) % a.loop_ns();
    EXPECT_EQ(d, 5'000'000);
    ASSERT_TRUE(a.next(fa));
    EXPECT_GE(monotonic_ns(), fa.capture_ns);  // real time: not delivered before its instant
}

TEST_F(PlaybackOfACapture, ErrorsNameTheProblem) {
    expect_input_error([&] { PlaybackSensor(root, "", {}); }, {"name one"});
    EXPECT_THROW(PlaybackSensor(root, "zz", {}), InputError);
    EXPECT_THROW(open_sensor("nokind"), InputError);
    EXPECT_THROW(open_sensor("bogus:x"), InputError);
    EXPECT_THROW(open_sensor("playback:" + (root / "missing").string()), Error);
    // A truncated depth image.
    const io::Capture cap = io::open_capture(root);
    const fs::path depth = root / "a" / cap.frames.at("a")[2].depth;
    fs::resize_file(depth, 20);
    EXPECT_THROW(PlaybackSensor(root, "a", {}), Error);
}

TEST_F(PlaybackOfACapture, RegistryOpensFolderSlashIdAndHashId) {
    OpenOptions o;
    o.playback.realtime = false;
    EXPECT_EQ(open_sensor("playback:" + (root / "b").string(), o)->spec().id, "b");
    EXPECT_EQ(open_sensor("playback:" + root.string() + "#a", o)->spec().id, "a");
}

TEST(SyntheticSensor, IsDeterministicAndKinectLike) {
    SyntheticOptions o;
    o.realtime = false;
    o.max_frames = 2;
    SyntheticSensor s(o);
    EXPECT_EQ(s.spec().depth.width, 512);
    SensorFrame f1, f2;
    ASSERT_TRUE(s.next(f1));
    cv::Mat d, c;
    s.render(0, d, c);
    EXPECT_EQ(cv::norm(d, f1.depth, cv::NORM_INF), 0.0);
    ASSERT_TRUE(s.next(f2));
    EXPECT_GT(cv::norm(f1.depth, f2.depth, cv::NORM_L1), 0.0);  // the sphere moves
    EXPECT_FALSE(s.next(f2));
    double lo = 0, hi = 0;
    cv::minMaxLoc(f1.depth, &lo, &hi);
    EXPECT_EQ(lo, 0.0);  // dropouts
    EXPECT_GT(hi, 2900.0);
    EXPECT_LT(hi, 3100.0);  // the wall at 3 m
    EXPECT_EQ(f1.color.cols, 640);
}

}  // namespace
}  // namespace rgbd::sensors

#ifdef RGBD_WITH_OPENNI2
namespace rgbd::sensors {
namespace {
TEST(OpenNi2Sensor, WithoutADeviceTheErrorSaysSo) {
    try {
        open_sensor("openni2:no-such-device-uri");
        FAIL() << "opened a device that does not exist";
    } catch (const IoError& e) {
        EXPECT_NE(std::string(e.what()).find("OpenNI2: no device"), std::string::npos) << e.what();
    }
}
}  // namespace
}  // namespace rgbd::sensors
#endif
