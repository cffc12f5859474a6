#include "io/video.hpp"

#include <draco/compression/decode.h>
#include <draco/compression/encode.h>
#include <draco/metadata/geometry_metadata.h>
#include <draco/point_cloud/point_cloud_builder.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>

#include "toolkit/error.hpp"

namespace rgbd::io {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

constexpr const char* kFrameKey = "rgbd.frame";
constexpr const char* kSetKey = "rgbd.set";
constexpr const char* kTimeKey = "rgbd.time_ns";
constexpr const char* kSpreadKey = "rgbd.spread_ns";
constexpr const char* kColorBitsKey = "rgbd.color_bits";

std::vector<std::uint8_t> read_all(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(path.string() + ": cannot open");
    return std::vector<std::uint8_t>((std::istreambuf_iterator<char>(in)),
                                     std::istreambuf_iterator<char>());
}

std::int64_t meta_int(const draco::GeometryMetadata* md, const char* key, std::int64_t fallback) {
    std::string text;
    if (!md || !md->GetEntryString(key, &text)) return fallback;
    try {
        return std::stoll(text);
    } catch (...) {
        return fallback;
    }
}

json frame_json(const VideoFrame& f) {
    return {{"frame", f.frame},          {"file", f.file},           {"set", f.set},
            {"time_ns", f.time_ns},      {"spread_ns", f.spread_ns}, {"sensors", f.sensors},
            {"points", f.points},        {"bytes", f.bytes},         {"hub_ms", f.hub_ms},
            {"latency_ms", f.latency_ms}};
}

}  // namespace

// ------------------------------------------------------------------------------ conversion

ColoredPoints to_colored_points(const PointCloud& cloud) {
    ColoredPoints out;
    out.xyz.reserve(cloud.size());
    for (auto i : cloud.points) {
        const Point_3& p = cloud.points.point(i);
        out.xyz.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()),
                             static_cast<float>(p.z()));
    }
    if (cloud.has_colors()) {
        const auto cm = cloud.colors();
        out.rgb.reserve(cloud.size());
        for (auto i : cloud.points) out.rgb.push_back(cm.get(i));
    }
    return out;
}

PointCloud to_point_cloud(const ColoredPoints& points) {
    PointCloud cloud;
    cloud.view.frame = ViewFrame::kWorld;
    cloud.points.reserve(points.size());
    std::optional<PointCloud::ColorMaps> cm;
    if (!points.rgb.empty()) cm = cloud.add_colors();
    for (std::size_t i = 0; i < points.size(); ++i) {
        const Eigen::Vector3f& p = points.xyz[i];
        const auto idx = cloud.points.insert(Point_3(p.x(), p.y(), p.z()));
        if (cm) cm->set(*idx, points.rgb[i]);
    }
    return cloud;
}

// ------------------------------------------------------------------------------ Draco

void DracoSettings::check() const {
    check_range("Draco: position quantum", position_quantum_m, Range::closed(1e-6, 0.1), "m");
    RGBD_CHECK(color_bits >= 1 && color_bits <= 8, "Draco: colour bits must be 1..8");
    RGBD_CHECK(speed >= 0 && speed <= 10, "Draco: speed must be 0..10");
}

json DracoSettings::to_json() const {
    return {
        {"position_quantum_m", position_quantum_m}, {"color_bits", color_bits}, {"speed", speed}};
}

std::vector<std::uint8_t> encode_draco(const ColoredPoints& points, const DracoSettings& settings,
                                       const FrameMeta& meta) {
    settings.check();
    RGBD_CHECK(points.rgb.empty() || points.rgb.size() == points.xyz.size(),
               "Draco: colour count differs from point count");
    const auto n = static_cast<draco::PointIndex::ValueType>(points.size());
    draco::PointCloudBuilder builder;
    builder.Start(n);
    const int pos = builder.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
    Eigen::Vector3f lo = Eigen::Vector3f::Zero(), hi = Eigen::Vector3f::Zero();
    if (n > 0) {
        lo = hi = points.xyz.front();
        for (const auto& p : points.xyz) {
            RGBD_CHECK(p.allFinite(), "Draco: non-finite point");
            lo = lo.cwiseMin(p);
            hi = hi.cwiseMax(p);
        }
        builder.SetAttributeValuesForAllPoints(pos, points.xyz.data(), sizeof(Eigen::Vector3f));
    }
    const int shift = 8 - settings.color_bits;
    if (!points.rgb.empty()) {
        const int col = builder.AddAttribute(draco::GeometryAttribute::COLOR, 3, draco::DT_UINT8);
        std::vector<std::uint8_t> rgb(3 * points.rgb.size());
        for (std::size_t i = 0; i < points.rgb.size(); ++i) {
            rgb[3 * i] = points.rgb[i].r >> shift;
            rgb[3 * i + 1] = points.rgb[i].g >> shift;
            rgb[3 * i + 2] = points.rgb[i].b >> shift;
        }
        if (n > 0) builder.SetAttributeValuesForAllPoints(col, rgb.data(), 3);
    }
    std::unique_ptr<draco::PointCloud> pc = builder.Finalize(false);
    RGBD_CHECK_AS(AlgorithmError, pc != nullptr, "Draco: cannot build the point cloud");
    auto md = std::make_unique<draco::GeometryMetadata>();
    md->AddEntryString(kFrameKey, std::to_string(meta.frame));
    md->AddEntryString(kSetKey, std::to_string(meta.set));
    md->AddEntryString(kTimeKey, std::to_string(meta.time_ns));
    md->AddEntryString(kSpreadKey, std::to_string(meta.spread_ns));
    md->AddEntryString(kColorBitsKey, std::to_string(settings.color_bits));
    pc->AddMetadata(std::move(md));

    draco::Encoder encoder;
    encoder.SetSpeedOptions(settings.speed, settings.speed);
    // An explicit grid: the quantum is the same in every frame, whatever the cloud's extent.
    const float extent = std::max(1e-6f, (hi - lo).maxCoeff());
    int bits = 1;
    while (bits < 30 &&
           static_cast<double>((1u << bits) - 1) * settings.position_quantum_m < extent)
        ++bits;
    const float range = static_cast<float>(settings.position_quantum_m * ((1u << bits) - 1));
    encoder.SetAttributeExplicitQuantization(draco::GeometryAttribute::POSITION, bits, 3, lo.data(),
                                             range);
    draco::EncoderBuffer buffer;
    const draco::Status status = encoder.EncodePointCloudToBuffer(*pc, &buffer);
    if (!status.ok()) throw AlgorithmError("Draco: cannot encode: " + status.error_msg_string());
    return std::vector<std::uint8_t>(buffer.data(), buffer.data() + buffer.size());
}

ColoredPoints decode_draco(const std::uint8_t* data, std::size_t size, const std::string& what,
                           FrameMeta* meta) {
    draco::DecoderBuffer buffer;
    buffer.Init(reinterpret_cast<const char*>(data), size);
    draco::Decoder decoder;
    auto result = decoder.DecodePointCloudFromBuffer(&buffer);
    if (!result.ok())
        throw InputError(what + ": not a Draco point cloud (" + result.status().error_msg_string() +
                         ")");
    std::unique_ptr<draco::PointCloud> pc = std::move(result).value();
    const draco::PointAttribute* pos = pc->GetNamedAttribute(draco::GeometryAttribute::POSITION);
    if (!pos || pos->num_components() != 3)
        throw InputError(what + ": Draco point cloud without 3D positions");
    const draco::PointAttribute* col = pc->GetNamedAttribute(draco::GeometryAttribute::COLOR);
    const draco::GeometryMetadata* md = pc->GetMetadata();
    const int color_bits = static_cast<int>(meta_int(md, kColorBitsKey, 8));
    const int shift = std::clamp(8 - color_bits, 0, 7);
    const int half = shift > 0 ? 1 << (shift - 1) : 0;
    ColoredPoints out;
    const auto n = pc->num_points();
    out.xyz.resize(n);
    if (col && col->num_components() >= 3) out.rgb.resize(n);
    for (draco::PointIndex i(0); i < n; ++i) {
        float p[3];
        if (!pos->ConvertValue<float, 3>(pos->mapped_index(i), p))
            throw InputError(what + ": cannot read a Draco position");
        out.xyz[i.value()] = Eigen::Vector3f(p[0], p[1], p[2]);
        if (!out.rgb.empty()) {
            std::uint8_t c[3];
            if (!col->ConvertValue<std::uint8_t, 3>(col->mapped_index(i), c))
                throw InputError(what + ": cannot read a Draco colour");
            out.rgb[i.value()] = Rgb{static_cast<std::uint8_t>((c[0] << shift) | half),
                                     static_cast<std::uint8_t>((c[1] << shift) | half),
                                     static_cast<std::uint8_t>((c[2] << shift) | half)};
        }
    }
    if (meta) {
        meta->frame = meta_int(md, kFrameKey, -1);
        meta->set = meta_int(md, kSetKey, -1);
        meta->time_ns = meta_int(md, kTimeKey, 0);
        meta->spread_ns = meta_int(md, kSpreadKey, 0);
    }
    return out;
}

// ------------------------------------------------------------------------------ folder

std::string video_frame_file(std::int64_t frame) {
    char name[48];
    std::snprintf(name, sizeof name, "frames/%06lld.drc", static_cast<long long>(frame));
    return name;
}

VideoInfo read_video(const fs::path& root) {
    const fs::path index = root / "video.json";
    if (!fs::exists(index)) throw InputError(root.string() + ": no video.json (not a 3D video)");
    json j;
    {
        std::ifstream in(index);
        if (!in) throw IoError(index.string() + ": cannot open");
        j = json::parse(in, nullptr, false);
    }
    if (!j.is_object() || j.value("format", "") != "rgbd-video")
        throw InputError(index.string() + ": not an rgbd-video index");
    if (j.value("version", 0) != 1)
        throw InputError(index.string() + ": unsupported version " + j["version"].dump());
    VideoInfo info;
    info.root = root;
    info.frame_rate_hz = j.value("frame_rate_hz", 0.0);
    info.complete = j.value("complete", false);
    std::map<std::int64_t, VideoFrame> frames;
    if (j.contains("frames")) {
        if (!j["frames"].is_array()) throw InputError(index.string() + ": 'frames' is not a list");
        for (const json& f : j["frames"]) {
            VideoFrame v;
            try {
                v.frame = f.at("frame").get<std::int64_t>();
                v.file = f.at("file").get<std::string>();
                v.set = f.value("set", std::int64_t{-1});
                v.time_ns = f.value("time_ns", std::int64_t{0});
                v.spread_ns = f.value("spread_ns", std::int64_t{0});
                v.sensors = f.value("sensors", 0);
                v.points = f.value("points", std::size_t{0});
                v.bytes = f.value("bytes", std::size_t{0});
                v.hub_ms = f.value("hub_ms", 0.0);
                v.latency_ms = f.value("latency_ms", 0.0);
            } catch (const json::exception& e) {
                throw InputError(index.string() + ": bad frame entry: " + e.what());
            }
            if (v.file.empty() || v.file.find("..") != std::string::npos)
                throw InputError(index.string() + ": bad file name '" + v.file + "'");
            frames[v.frame] = v;
        }
    }
    j.erase("frames");
    info.header = j;
    // Check every indexed file: present, size as written, Draco magic.
    for (auto& [number, v] : frames) {
        const fs::path path = root / v.file;
        std::error_code ec;
        const auto size = fs::file_size(path, ec);
        if (ec) {
            v.problem = "missing";
        } else if (size != v.bytes) {
            v.problem = "size " + std::to_string(size) + " bytes, the index says " +
                        std::to_string(v.bytes) + " (stale or truncated)";
        } else {
            char magic[5] = {0, 0, 0, 0, 0};
            std::ifstream in(path, std::ios::binary);
            in.read(magic, 5);
            if (!in || std::string(magic, 5) != "DRACO") v.problem = "not a Draco file";
        }
    }
    // Frame files written after the last index update (a capture cut short).
    const fs::path dir = root / "frames";
    if (fs::is_directory(dir)) {
        for (const auto& entry : fs::directory_iterator(dir)) {
            const std::string name = entry.path().filename().string();
            if (entry.path().extension() != ".drc" || name.size() < 5) continue;
            std::int64_t number = -1;
            try {
                std::size_t used = 0;
                number = std::stoll(name.substr(0, name.size() - 4), &used);
                if (used != name.size() - 4) number = -1;
            } catch (...) {
            }
            if (number < 0 || frames.count(number)) continue;
            VideoFrame v;
            v.frame = number;
            v.file = "frames/" + name;
            v.indexed = false;
            try {
                const auto bytes = read_all(entry.path());
                FrameMeta meta;
                const ColoredPoints points =
                    decode_draco(bytes.data(), bytes.size(), entry.path().string(), &meta);
                v.set = meta.set;
                v.time_ns = meta.time_ns;
                v.spread_ns = meta.spread_ns;
                v.points = points.size();
                v.bytes = bytes.size();
            } catch (const Error& e) {
                v.problem = e.what();
            }
            frames[number] = v;
        }
    }
    for (auto& [number, v] : frames) info.frames.push_back(std::move(v));
    return info;
}

ColoredPoints read_video_frame(const VideoInfo& video, std::int64_t frame, FrameMeta* meta) {
    const auto it = std::find_if(video.frames.begin(), video.frames.end(),
                                 [&](const VideoFrame& f) { return f.frame == frame; });
    if (it == video.frames.end())
        throw InputError(video.root.string() + ": no frame " + std::to_string(frame) + " (" +
                         std::to_string(video.frames.size()) + " frames)");
    const fs::path path = video.root / it->file;
    if (!it->problem.empty()) throw InputError(path.string() + ": " + it->problem);
    const auto bytes = read_all(path);
    return decode_draco(bytes.data(), bytes.size(), path.string(), meta);
}

// ------------------------------------------------------------------------------ writer

VideoWriter::VideoWriter(const fs::path& root, const Rig& rig, double frame_rate_hz,
                         const DracoSettings& draco, const json& header, double index_interval_s)
    : root_(root), draco_(draco), index_interval_s_(index_interval_s) {
    draco.check();
    std::error_code ec;
    if (fs::exists(root, ec)) {
        if (!fs::is_directory(root) || !fs::is_empty(root))
            throw IoError(root.string() + ": exists and is not an empty folder");
    }
    fs::create_directories(root / "frames", ec);
    if (ec) throw IoError(root.string() + ": cannot create the folder: " + ec.message());
    write_rig(root / "rig.json", rig);
    json rig_json;
    {
        std::ifstream in(root / "rig.json");
        rig_json = json::parse(in, nullptr, false);
    }
    header_ = header.is_object() ? header : json::object();
    header_["format"] = "rgbd-video";
    header_["version"] = 1;
    header_["frame_rate_hz"] = frame_rate_hz;
    header_["rig"] = rig_json;
    header_["draco"] = draco.to_json();
    header_["complete"] = false;
    write_index();
}

VideoWriter::~VideoWriter() = default;

const VideoFrame& VideoWriter::add(const ColoredPoints& points, VideoFrame info) {
    info.frame = frames();
    info.file = video_frame_file(info.frame);
    info.points = points.size();
    const auto bytes =
        encode_draco(points, draco_, FrameMeta{info.frame, info.set, info.time_ns, info.spread_ns});
    write_bytes_atomic(root_ / info.file, bytes.data(), bytes.size());
    info.bytes = bytes.size();
    bytes_ += bytes.size();
    frames_.push_back(std::move(info));
    return frames_.back();
}

void VideoWriter::update_last(double hub_ms, double latency_ms) {
    if (frames_.empty()) return;
    frames_.back().hub_ms = hub_ms;
    frames_.back().latency_ms = latency_ms;
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - last_index_).count() >=
        index_interval_s_)
        write_index();
}

void VideoWriter::write_index() {
    json j = header_;
    json list = json::array();
    for (const VideoFrame& f : frames_) list.push_back(frame_json(f));
    j["frames"] = std::move(list);
    write_text_atomic(root_ / "video.json", j.dump(1) + "\n");
    last_index_ = std::chrono::steady_clock::now();
}

void VideoWriter::finish(const json& counters, const std::string& stop_reason) {
    header_["counters"] = counters;
    header_["stop_reason"] = stop_reason;
    header_["complete"] = true;
    write_index();
}

}  // namespace rgbd::io
