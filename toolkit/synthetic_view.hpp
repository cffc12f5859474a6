// The view that holds the points a stage makes rather than measures (hole filling, stand contact
// points): world frame, flagged prop::kSynthetic (docs/formats.md).
#pragma once

#include <string>

#include "toolkit/point_cloud.hpp"

namespace rgbd {

/// An empty world-frame view with id `id` and sensor name `sensor`, holding a normal map, the
/// colour maps and the prop::kSynthetic flag, in that property order. Fill it through colors()
/// and flag(prop::kSynthetic).
PointCloud synthetic_world_view(int id, std::string sensor);

}  // namespace rgbd
