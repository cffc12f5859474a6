#include "toolkit/point_cloud.hpp"

#include <stdexcept>

#include "toolkit/error.hpp"

namespace rgbd {

namespace {
template <typename T>
std::optional<PointSet::Property_map<T>> find_map(const PointSet& points, const char* name) {
    auto [map, found] = points.template property_map<T>(name);
    if (!found) return std::nullopt;
    return map;
}
template <typename T>
PointSet::Property_map<T> add_map(PointSet& points, const char* name, T value) {
    return points.template add_property_map<T>(name, value).first;
}
}  // namespace

bool PointCloud::has_colors() const {
    return find_map<std::uint8_t>(points, prop::kRed) &&
           find_map<std::uint8_t>(points, prop::kGreen) &&
           find_map<std::uint8_t>(points, prop::kBlue);
}

PointCloud::ColorMaps PointCloud::add_colors() {
    return {add_map<std::uint8_t>(points, prop::kRed, 0),
            add_map<std::uint8_t>(points, prop::kGreen, 0),
            add_map<std::uint8_t>(points, prop::kBlue, 0)};
}

PointCloud::ColorMaps PointCloud::colors() const {
    auto r = find_map<std::uint8_t>(points, prop::kRed);
    auto g = find_map<std::uint8_t>(points, prop::kGreen);
    auto b = find_map<std::uint8_t>(points, prop::kBlue);
    if (!r || !g || !b) throw std::logic_error("point cloud has no colours");
    return {*r, *g, *b};
}

PointCloud::Uint8Map PointCloud::add_flag(const char* name) {
    return add_map<std::uint8_t>(points, name, 0);
}
std::optional<PointCloud::Uint8Map> PointCloud::flag(const char* name) const {
    return find_map<std::uint8_t>(points, name);
}
PointCloud::Uint32Map PointCloud::add_pixel_map() {
    return add_map<std::uint32_t>(points, prop::kPixel, 0);
}
std::optional<PointCloud::Uint32Map> PointCloud::pixel_map() const {
    return find_map<std::uint32_t>(points, prop::kPixel);
}
PointCloud::FloatMap PointCloud::add_float(const char* name, float default_value) {
    return add_map<float>(points, name, default_value);
}
std::optional<PointCloud::FloatMap> PointCloud::float_map(const char* name) const {
    return find_map<float>(points, name);
}
PointCloud::Int32Map PointCloud::add_view_map() {
    return add_map<std::int32_t>(points, prop::kView, 0);
}
std::optional<PointCloud::Int32Map> PointCloud::view_map() const {
    return find_map<std::int32_t>(points, prop::kView);
}

std::vector<std::string> PointCloud::property_names() const {
    std::vector<std::string> names;
    for (const std::string& name : points.properties())
        if (name != "index" && name != "point" && name != "normal") names.push_back(name);
    return names;
}

void transform(PointCloud& cloud, const Pose& target_from_source) {
    const Eigen::Matrix3d r = target_from_source.linear();
    const bool normals = cloud.points.has_normal_map();
    for (auto idx : cloud.points) {
        cloud.points.point(idx) = to_point(target_from_source * to_eigen(cloud.points.point(idx)));
        if (normals) cloud.points.normal(idx) = to_vector(r * to_eigen(cloud.points.normal(idx)));
    }
}

void to_world_frame(PointCloud& cloud) {
    if (cloud.view.frame == ViewFrame::kWorld) return;
    RGBD_CHECK(cloud.view.world_from_sensor.has_value(),
               "view " + std::to_string(cloud.view.id) + " has no world_from_sensor pose");
    transform(cloud, *cloud.view.world_from_sensor);
    cloud.view.frame = ViewFrame::kWorld;
}

}  // namespace rgbd
