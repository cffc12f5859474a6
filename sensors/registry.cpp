#include "sensors/registry.hpp"

#include <filesystem>

#include "sensors/synthetic/synthetic_sensor.hpp"
#include "toolkit/error.hpp"
#ifdef RGBD_WITH_OPENNI2
#include "sensors/openni2/openni2_sensor.hpp"
#endif

namespace rgbd::sensors {

namespace fs = std::filesystem;

std::unique_ptr<Sensor> open_sensor(const std::string& what, const OpenOptions& options) {
    const auto colon = what.find(':');
    if (colon == std::string::npos)
        throw InputError("sensor '" + what +
                         "': expected KIND:ARGUMENT (playback:FOLDER[#ID], synthetic:[ID]" +
#ifdef RGBD_WITH_OPENNI2
                         ", openni2:[URI]" +
#endif
                         ")");
    const std::string kind = what.substr(0, colon), arg = what.substr(colon + 1);
    if (kind == "playback") {
        PlaybackOptions p = options.playback;
        if (options.max_frames > 0) p.max_frames = options.max_frames;
        std::string folder = arg, id;
        if (const auto hash = arg.rfind('#'); hash != std::string::npos) {
            folder = arg.substr(0, hash);
            id = arg.substr(hash + 1);
        } else {
            const fs::path path(arg);
            // CAPTURE/ID: a sensor folder inside a capture folder v1
            const fs::path trimmed = path.filename().empty() ? path.parent_path() : path;
            if (!fs::exists(trimmed / "rig.json") &&
                fs::exists(trimmed.parent_path() / "rig.json")) {
                folder = trimmed.parent_path().string();
                id = trimmed.filename().string();
            }
        }
        if (folder.empty()) throw InputError("sensor '" + what + "': no folder given");
        return std::make_unique<PlaybackSensor>(folder, id, p);
    }
    if (kind == "synthetic") {
        SyntheticOptions s;
        if (!arg.empty()) s.id = arg;
        s.rate_hz = options.rate_hz;
        s.max_frames = options.max_frames;
        return std::make_unique<SyntheticSensor>(s);
    }
#ifdef RGBD_WITH_OPENNI2
    if (kind == "openni2") {
        OpenNi2Options o;
        o.uri = arg;
        o.max_frames = options.max_frames;
        return std::make_unique<OpenNi2Sensor>(o);
    }
#endif
    throw InputError("sensor '" + what + "': unknown kind '" + kind + "'");
}

}  // namespace rgbd::sensors
