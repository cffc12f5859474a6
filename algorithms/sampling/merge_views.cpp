#include "algorithms/sampling/merge_views.hpp"

#include <algorithm>
#include <map>
#include <string>
#include <typeindex>

#include "toolkit/error.hpp"

namespace rgbd::sampling {

namespace {
void append_unique(std::vector<std::string>& into, const std::vector<std::string>& lines) {
    for (const std::string& line : lines)
        if (std::find(into.begin(), into.end(), line) == into.end()) into.push_back(line);
}
}  // namespace

PointCloud merge_views(std::vector<PointCloud>&& views) {
    PointCloud out;
    out.view.id = 0;
    out.view.sensor = "merged";
    out.view.frame = ViewFrame::kWorld;

    // Property union, with a type check per name.
    std::map<std::string, std::type_index> types;
    bool all_normals = true;
    std::size_t total = 0;
    for (PointCloud& view : views) {
        to_world_frame(view);
        for (const auto& [name, type] : view.points.properties_and_types()) {
            if (name == "index" || name == "point") continue;
            auto [it, inserted] = types.emplace(name, type);
            RGBD_CHECK(inserted || it->second == type,
                       "merge_views: view " + std::to_string(view.view.id) + ": property '" + name +
                           "' has a different type than in an earlier view");
        }
        if (!view.empty() && !view.points.has_normal_map()) all_normals = false;
        total += view.size();
        append_unique(out.view.history, view.view.history);
        append_unique(out.view.extra_comments, view.view.extra_comments);
    }
    for (PointCloud& view : views) out.points.copy_properties(view.points);
    if (!all_normals && out.points.has_normal_map()) out.points.remove_normal_map();
    auto view_ids = out.add_view_map();
    out.points.reserve(total);

    for (PointCloud& view : views) {
        const bool keep_ids = view.view.sensor == "merged" && view.view_map().has_value();
        const std::size_t begin = out.points.size();
        out.points.join(view.points);
        if (keep_ids) continue;
        const auto id = static_cast<std::int32_t>(view.view.id);
        for (std::size_t i = begin; i < out.points.size(); ++i)
            view_ids[PointSet::Index(static_cast<std::uint32_t>(i))] = id;
        view.points.clear();
    }
    views.clear();
    return out;
}

}  // namespace rgbd::sampling
