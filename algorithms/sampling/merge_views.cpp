#include "algorithms/sampling/merge_views.hpp"

#include <algorithm>
#include <iterator>
#include <map>
#include <string>
#include <typeindex>
#include <typeinfo>

#include "toolkit/error.hpp"

namespace rgbd::sampling {

namespace {
void append_unique(std::vector<std::string>& into, const std::vector<std::string>& lines) {
    for (const std::string& line : lines)
        if (std::find(into.begin(), into.end(), line) == into.end()) into.push_back(line);
}

/// Copies property `name` of type T of every live point of `from`, in iteration order, to
/// `into` from position `begin` on. False when `from` has no such property of type T.
template <typename T>
bool copy_column(const PointSet& from, PointSet& into, const std::string& name, std::size_t begin) {
    const auto source = from.property_map<T>(name);
    if (!source.second) return false;
    const auto target = into.property_map<T>(name);
    if (!target.second) return false;
    std::size_t i = begin;
    for (PointSet::Index idx : from)
        target.first[PointSet::Index(static_cast<std::uint32_t>(i++))] = source.first[idx];
    return true;
}

/// The property types copied column by column; a view with any other type is joined.
bool copy_any_column(const PointSet& from, PointSet& into, const std::string& name,
                     std::size_t begin) {
    return copy_column<Point_3>(from, into, name, begin) ||
           copy_column<Vector_3>(from, into, name, begin) ||
           copy_column<float>(from, into, name, begin) ||
           copy_column<double>(from, into, name, begin) ||
           copy_column<std::uint8_t>(from, into, name, begin) ||
           copy_column<std::int8_t>(from, into, name, begin) ||
           copy_column<std::uint16_t>(from, into, name, begin) ||
           copy_column<std::int16_t>(from, into, name, begin) ||
           copy_column<std::uint32_t>(from, into, name, begin) ||
           copy_column<std::int32_t>(from, into, name, begin) ||
           copy_column<std::uint64_t>(from, into, name, begin) ||
           copy_column<std::int64_t>(from, into, name, begin) ||
           copy_column<bool>(from, into, name, begin);
}

bool column_type_known(const std::type_index& type) {
    static const std::type_index known[] = {
        typeid(Point_3),       typeid(Vector_3),     typeid(float),         typeid(double),
        typeid(std::uint8_t),  typeid(std::int8_t),  typeid(std::uint16_t), typeid(std::int16_t),
        typeid(std::uint32_t), typeid(std::int32_t), typeid(std::uint64_t), typeid(std::int64_t),
        typeid(bool)};
    return std::find(std::begin(known), std::end(known), type) != std::end(known);
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
    // Column by column into a point set sized once: Point_set_3::join collects the garbage of
    // the growing result at every call (a sort of all its properties, then a shrink), which
    // made merging V views O(V N log N). Same result: join appends the live points of each
    // view in iteration order, properties missing in a view keep the default value.
    bool columns = true;
    for (const auto& [name, type] : types) columns = columns && column_type_known(type);
    if (columns) out.points.resize(total);
    std::size_t begin = 0;
    for (PointCloud& view : views) {
        const bool keep_ids = view.view.sensor == "merged" && view.view_map().has_value();
        const std::size_t size = view.points.size();
        if (columns) {
            std::size_t i = begin;
            for (PointSet::Index idx : view.points)
                out.points.point(PointSet::Index(static_cast<std::uint32_t>(i++))) =
                    view.points.point(idx);
            // properties_and_types() lists every property but "index" and "point".
            for (const auto& [name, type] : view.points.properties_and_types())
                if (name != "normal" || out.points.has_normal_map())
                    copy_any_column(view.points, out.points, name, begin);
        } else {
            out.points.join(view.points);
        }
        if (!keep_ids) {
            const auto id = static_cast<std::int32_t>(view.view.id);
            for (std::size_t i = begin; i < begin + size; ++i)
                view_ids[PointSet::Index(static_cast<std::uint32_t>(i))] = id;
        }
        begin += size;
        view.points.clear();
    }
    views.clear();
    return out;
}

}  // namespace rgbd::sampling
