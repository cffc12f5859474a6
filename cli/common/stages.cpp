#include "cli/common/stages.hpp"

#include <algorithm>

#include "cli/common/tool.hpp"
#include "toolkit/error.hpp"

namespace rgbd::cli {

std::vector<std::pair<std::string, std::size_t>> select_frames(
    const io::Capture& capture, long long frameset, const std::string& frames,
    const std::vector<std::string>& sensors, const Context* context) {
    const std::string root = capture.root.string();
    for (const auto& id : sensors) capture.rig.sensor(id);  // throws for unknown ids
    auto wanted = [&](const std::string& id) {
        return sensors.empty() || std::find(sensors.begin(), sensors.end(), id) != sensors.end();
    };
    std::vector<std::pair<std::string, std::size_t>> jobs;
    const bool multi = capture.rig.sensors.size() > 1 && !capture.framesets.empty();
    if (multi && frames.empty()) {
        if (frameset < 0 || frameset >= static_cast<long long>(capture.framesets.size()))
            throw UsageError("--frameset " + std::to_string(frameset) + " is out of range (" +
                             std::to_string(capture.framesets.size()) + " frame sets)");
        const io::FrameSet& set = capture.framesets[frameset];
        for (std::size_t s = 0; s < capture.rig.sensors.size(); ++s) {
            const std::string& id = capture.rig.sensors[s].id;
            if (!wanted(id)) continue;
            if (s >= set.frames.size() || set.frames[s] < 0) {
                if (context)
                    context->warn("frame set " + std::to_string(frameset) + ": sensor " + id +
                                  " is missing");
                continue;
            }
            const auto position = capture.find_frame(id, set.frames[s]);
            if (!position)
                throw InputError(root + ": frame set " + std::to_string(frameset) +
                                 " names frame " + std::to_string(set.frames[s]) + " of sensor " +
                                 id + ", which its frames.csv does not list");
            jobs.emplace_back(id, *position);
        }
    } else {
        for (const auto& sensor : capture.rig.sensors) {
            if (!wanted(sensor.id)) continue;
            const auto it = capture.frames.find(sensor.id);
            if (it == capture.frames.end()) continue;
            const long long count = static_cast<long long>(it->second.size());
            std::vector<long long> positions;
            if (!frames.empty()) {
                positions = parse_range(frames, count);
            } else if (multi) {
                positions = {0};
            } else {
                for (long long i = 0; i < count; ++i) positions.push_back(i);
            }
            for (long long p : positions) {
                if (p >= count)
                    throw UsageError("--frames: position " + std::to_string(p) +
                                     " is out of range (sensor " + sensor.id + " has " +
                                     std::to_string(count) + " frames)");
                jobs.emplace_back(sensor.id, static_cast<std::size_t>(p));
            }
        }
    }
    if (jobs.empty()) throw InputError(root + ": no frames selected");
    return jobs;
}

std::vector<PointCloud> read_point_views(Context& context) {
    std::vector<PointCloud> views;
    for (auto& document : context.read_all_documents()) {
        if (document.kind == io::DocumentKind::kMesh)
            throw InputError(context.spec().name + " takes point views, not meshes (document " +
                             std::to_string(views.size() + 1) + ")");
        views.push_back(std::move(document.cloud));
    }
    return views;
}

void warn_refused_colour_poses(Context& context, const Report& texture_report) {
    if (!texture_report.contains("refine")) return;
    const Report& refine = texture_report["refine"];
    for (const auto& c : refine["cameras"])
        if (c["status"] == "refused")
            context.warn(c["view"].get<std::string>() + ": colour pose refinement refused (" +
                         c["reason"].get<std::string>() + "); the original pose is kept");
    context.note(
        formatted("colour poses: %d refined, %d refused; photometric residual %.2f -> "
                  "%.2f grey levels",
                  refine["refined"].get<int>(), refine["refused"].get<int>(),
                  refine["residual_before"].get<double>(), refine["residual_after"].get<double>()));
}

}  // namespace rgbd::cli
