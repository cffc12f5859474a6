#include "toolkit/synthetic_view.hpp"

#include <utility>

namespace rgbd {

PointCloud synthetic_world_view(int id, std::string sensor) {
    PointCloud cloud;
    cloud.view.id = id;
    cloud.view.sensor = std::move(sensor);
    cloud.view.frame = ViewFrame::kWorld;
    cloud.points.add_normal_map();
    cloud.add_colors();
    cloud.add_flag(prop::kSynthetic);
    return cloud;
}

}  // namespace rgbd
