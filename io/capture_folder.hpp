// Capture folders (docs/formats.md): capture folder v1 (rig.json, framesets.csv, per-sensor
// frames.csv with depth/ and color/ images, gt/ for synthetic captures), plus read-only
// layouts: TUM RGB-D, Open3D/Redwood (intrinsic JSON + .log trajectory), the
// "frames with OpenCV camera xml" layout of shared/data/multiview/uva_cv2_person_kinect1 and the
// APC vision toolbox scene layout (cam.info.txt + frame-NNNNNN.{color,depth}.png, Zeng et al.,
// ICRA 2017) of shared/data/multiview/apc_realsense_f200_shelf.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "toolkit/camera.hpp"
#include "toolkit/pose.hpp"
#include "toolkit/rgbd_frame.hpp"

namespace rgbd::io {

/// How a layout stores depth values in its 16-bit depth PNGs.
enum class DepthEncoding {
    kPlain,        ///< the value is the depth in depth_scale units (capture folders, TUM, ...)
    kApcRotated3,  ///< APC vision toolbox: bits rotated right by 3, d = (v << 13 | v >> 3) & 0xFFFF
};

/// "plain" or "apc_rotated3".
std::string to_string(DepthEncoding encoding);

/// Undoes `encoding` on a stored depth image (CV_16UC1) in place, so that its values are depth
/// in depth_scale units (0 stays 0 = invalid). kPlain returns at once without touching pixels.
void decode_depth(cv::Mat& stored, DepthEncoding encoding);

/// One sensor of rig.json.
struct SensorSpec {
    std::string id;
    std::string model;  ///< "kinect_v2", "sr300", ... (free text)
    PinholeIntrinsics depth;
    PinholeIntrinsics color;
    double depth_scale = 1000.0;  ///< stored value / depth_scale = metres
    /// How the layout's depth files store values; load_frame (and the playback sensor) undo it
    /// when they read a file, so every depth image past them is plain. Not in rig.json: capture
    /// folders v1 always store plain values (write_rig drops it, the writers write plain).
    DepthEncoding depth_encoding = DepthEncoding::kPlain;
    double range_min_m = 0.0;  ///< valid depth range (0 = unknown)
    double range_max_m = 0.0;
    Pose color_from_depth = Pose::Identity();
    Pose world_from_depth = Pose::Identity();
    /// world_from_depth is known (rig.json has the key). Layouts without poses set false;
    /// write_rig omits the key then.
    bool has_world_from_depth = true;
    std::string noise_model;                          ///< noise.model ("" = none given)
    std::int64_t clock_offset_ns = 0;                 ///< clock.offset_ns
    nlohmann::json extra = nlohmann::json::object();  ///< unknown keys, kept verbatim
};

/// rig.json.
struct Rig {
    std::vector<SensorSpec> sensors;
    nlohmann::json extra = nlohmann::json::object();  ///< unknown top-level keys

    /// Throws InputError naming the id when absent.
    const SensorSpec& sensor(const std::string& id) const;
};

/// Reads and validates rig.json. Errors name the file and the problem (InputError/IoError).
Rig read_rig(const std::filesystem::path& path);
/// Writes rig.json atomically (temporary file, then rename).
void write_rig(const std::filesystem::path& path, const Rig& rig);

/// One line of <sensor>/frames.csv.
struct FrameRecord {
    std::int64_t index = 0;
    std::int64_t time_ns = 0;  ///< the sensor's own clock
    std::string depth;         ///< path relative to the sensor folder (or absolute)
    std::string color;         ///< may be empty: no colour image
    std::string mask;  ///< optional object mask on the depth grid (uva layout); may be empty
    std::optional<Pose> world_from_depth;  ///< per-frame pose (turntable, hand-held)
};

/// One line of framesets.csv: the frame index per sensor (in Rig::sensors order; -1 = missing).
struct FrameSet {
    std::int64_t set = 0;
    std::int64_t time_ns = 0;  ///< hub time
    std::int64_t spread_ns = 0;
    std::vector<std::int64_t> frames;
};

/// An opened capture: the rig, the frame lists and the frame sets.
struct Capture {
    std::filesystem::path root;
    std::string layout;  ///< "rgbd-capture", "tum", "redwood", "uva", "apc"
    Rig rig;
    std::map<std::string, std::vector<FrameRecord>> frames;  ///< by sensor id, in file order
    std::vector<FrameSet> framesets;  ///< empty for single-sensor layouts without framesets.csv

    /// Position in frames.at(sensor_id) of the record with that index, or nullopt.
    std::optional<std::size_t> find_frame(const std::string& sensor_id, std::int64_t index) const;
};

/// Opens a capture folder of any supported layout (detected from its files). Reads only
/// the small files; images are read by load_frame. Throws InputError/IoError naming the file.
Capture open_capture(const std::filesystem::path& root);

/// Loads one frame (depth in metres with NaN for invalid, colour BGR, mask if the layout has
/// one) with the sensor's intrinsics, extrinsics, range and the frame's pose (per-frame pose
/// overrides the sensor's). Hub time = time_ns - clock_offset_ns. Errors name the file.
RgbdFrame load_frame(const Capture& capture, const std::string& sensor_id, std::size_t position);

/// A frame from images in their stored form, as load_frame builds it from a capture's files:
/// `depth_raw` CV_16UC1 in the sensor's depth_scale units (0 = invalid), `color_bgr` CV_8UC3
/// (may be empty), with the sensor's intrinsics, extrinsics, pose, range and noise model.
/// The caller sets frame_index, timestamp_ns and source. `what` names the images in errors
/// (a file, or e.g. "live frame of sensor k2_0"); sizes must match the rig (InputError).
RgbdFrame frame_from_stored(const SensorSpec& sensor, const cv::Mat& depth_raw,
                            const cv::Mat& color_bgr, const std::string& what);

/// Writes a capture folder v1. Files are written atomically; csv lines are appended and
/// flushed one by one, so an interrupted recording stays readable.
class CaptureWriter {
public:
    /// Creates root (must not exist or be empty) and writes rig.json.
    CaptureWriter(const std::filesystem::path& root, const Rig& rig);
    ~CaptureWriter();
    CaptureWriter(const CaptureWriter&) = delete;
    CaptureWriter& operator=(const CaptureWriter&) = delete;

    /// Writes depth (CV_32FC1 metres, NaN/0 = invalid; stored as uint16 PNG with the
    /// sensor's depth_scale) and colour (CV_8UC3 BGR, JPEG; may be empty) and appends the
    /// frames.csv line. `world_from_depth` is written as the 12 optional columns.
    void add_frame(const std::string& sensor_id, std::int64_t index, std::int64_t time_ns,
                   const cv::Mat& depth_m, const cv::Mat& color_bgr,
                   const std::optional<Pose>& world_from_depth = std::nullopt);
    /// Writes a frame whose images are already in their stored form: `depth_raw` CV_16UC1 in
    /// the sensor's depth_scale units (written as PNG with `png_compression` 0-9, bit for bit),
    /// `color_jpeg` the bytes of a JPEG file (written unchanged; empty = no colour), then
    /// appends the frames.csv line (no pose columns). Used by the capture hub, which receives
    /// compressed frames and must not re-encode colour. Throws IoError naming the file.
    void add_encoded_frame(const std::string& sensor_id, std::int64_t index, std::int64_t time_ns,
                           const cv::Mat& depth_raw, const std::vector<std::uint8_t>& color_jpeg,
                           int png_compression = 1);
    /// Appends a framesets.csv line (frames in Rig::sensors order, -1 = missing).
    void add_frameset(const FrameSet& set);
    const std::filesystem::path& root() const { return root_; }
    /// Where add_encoded_frame / add_frame put the depth image of a frame (root/sensor/depth/
    /// NNNNNN.png), the path load_frame reports as the frame's source.
    std::filesystem::path depth_file(const std::string& sensor_id, std::int64_t index) const;

private:
    std::filesystem::path root_;
    Rig rig_;
    bool framesets_header_written_ = false;
};

/// Writes an image atomically (temporary file in the same folder, then rename); the format
/// follows the extension (.png, .jpg; io/image_codec.hpp), with `level_or_quality` the PNG
/// zlib level or the JPEG quality (< 0: PNG level 1, JPEG quality 95). Throws IoError naming
/// the file (for another extension or image type too; InputError for an empty image).
void write_image_atomic(const std::filesystem::path& path, const cv::Mat& image,
                        int level_or_quality = -1);
/// Writes bytes atomically. Throws IoError naming the file.
void write_bytes_atomic(const std::filesystem::path& path, const std::uint8_t* data,
                        std::size_t size);
/// Writes text atomically. Throws IoError naming the file.
void write_text_atomic(const std::filesystem::path& path, const std::string& text);

}  // namespace rgbd::io
