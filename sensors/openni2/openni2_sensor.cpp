#include "sensors/openni2/openni2_sensor.hpp"

#include <OpenNI.h>

#include <cmath>
#include <cstring>
#include <opencv2/imgproc.hpp>

#include "toolkit/error.hpp"

namespace rgbd::sensors {

struct OpenNi2Sensor::Device {
    openni::Device device;
    openni::VideoStream depth, color;
    openni::VideoFrameRef depth_frame, color_frame;
    bool has_color = false;
};

namespace {

[[noreturn]] void fail(const std::string& what) {
    throw IoError("OpenNI2: " + what + ": " + openni::OpenNI::getExtendedError());
}

PinholeIntrinsics intrinsics_of(const openni::VideoStream& stream) {
    const openni::VideoMode mode = stream.getVideoMode();
    PinholeIntrinsics k;
    k.width = mode.getResolutionX();
    k.height = mode.getResolutionY();
    k.fx = k.width / 2.0 / std::tan(stream.getHorizontalFieldOfView() / 2.0);
    k.fy = k.height / 2.0 / std::tan(stream.getVerticalFieldOfView() / 2.0);
    k.cx = (k.width - 1) / 2.0;
    k.cy = (k.height - 1) / 2.0;
    return k;
}

}  // namespace

OpenNi2Sensor::OpenNi2Sensor(const OpenNi2Options& options)
    : device_(std::make_unique<Device>()), options_(options) {
    if (openni::OpenNI::initialize() != openni::STATUS_OK) fail("cannot initialise");
    if (device_->device.open(options.uri.empty() ? openni::ANY_DEVICE : options.uri.c_str()) !=
        openni::STATUS_OK)
        fail("no device" + (options.uri.empty() ? std::string() : " '" + options.uri + "'"));
    if (device_->depth.create(device_->device, openni::SENSOR_DEPTH) != openni::STATUS_OK)
        fail("no depth stream");
    openni::VideoMode mode = device_->depth.getVideoMode();
    mode.setPixelFormat(openni::PIXEL_FORMAT_DEPTH_1_MM);
    if (device_->depth.setVideoMode(mode) != openni::STATUS_OK) fail("cannot set depth to 1 mm");
    if (device_->depth.start() != openni::STATUS_OK) fail("cannot start depth");
    rate_hz_ = device_->depth.getVideoMode().getFps();
    spec_.id = options.id;
    spec_.model = device_->device.getDeviceInfo().getName();
    spec_.depth = intrinsics_of(device_->depth);
    spec_.depth_scale = 1000.0;
    spec_.noise_model = "kinect_v1";
    if (options.color && device_->device.hasSensor(openni::SENSOR_COLOR) &&
        device_->color.create(device_->device, openni::SENSOR_COLOR) == openni::STATUS_OK) {
        openni::VideoMode cm = device_->color.getVideoMode();
        cm.setPixelFormat(openni::PIXEL_FORMAT_RGB888);
        device_->color.setVideoMode(cm);
        if (device_->color.start() == openni::STATUS_OK) {
            device_->has_color = true;
            spec_.color = intrinsics_of(device_->color);
        }
    }
    if (!device_->has_color) spec_.color = spec_.depth;
}

OpenNi2Sensor::~OpenNi2Sensor() {
    device_->depth.stop();
    if (device_->has_color) device_->color.stop();
    device_->depth.destroy();
    device_->color.destroy();
    device_->device.close();
    openni::OpenNI::shutdown();
}

bool OpenNi2Sensor::next(SensorFrame& frame) {
    if (options_.max_frames > 0 && produced_ >= options_.max_frames) return false;
    if (device_->depth.readFrame(&device_->depth_frame) != openni::STATUS_OK)
        fail("cannot read a depth frame");
    const std::int64_t arrival = monotonic_ns();
    const openni::VideoFrameRef& d = device_->depth_frame;
    frame.depth.create(d.getHeight(), d.getWidth(), CV_16UC1);
    for (int y = 0; y < d.getHeight(); ++y)
        std::memcpy(frame.depth.ptr(y),
                    static_cast<const std::uint8_t*>(d.getData()) +
                        static_cast<std::size_t>(y) * d.getStrideInBytes(),
                    static_cast<std::size_t>(d.getWidth()) * 2);
    frame.color_jpeg.clear();
    if (device_->has_color &&
        device_->color.readFrame(&device_->color_frame) == openni::STATUS_OK) {
        const openni::VideoFrameRef& c = device_->color_frame;
        const cv::Mat rgb(c.getHeight(), c.getWidth(), CV_8UC3, const_cast<void*>(c.getData()),
                          static_cast<std::size_t>(c.getStrideInBytes()));
        cv::cvtColor(rgb, frame.color, cv::COLOR_RGB2BGR);
    } else {
        frame.color.release();
    }
    frame.index = produced_++;
    frame.device_ns = static_cast<std::int64_t>(d.getTimestamp()) * 1000;  // microseconds
    frame.capture_ns = arrival;  // host arrival: the device clock is mapped by the hub's fit
    frame.source_position = -1;
    return true;
}

}  // namespace rgbd::sensors
