// Merge of aligned views into one cloud (docs/method.md "merge"). Plain concatenation with
// the source view recorded per point; the duplicate removal of §6.2 step 6 is a separate stage.
// Source: CGAL Point_set_3::join / copy_properties. See also: algorithms/registration/icp.hpp
// (align_views gives the poses), algorithms/sampling/voxel_downsample.hpp.
#pragma once

#include <vector>

#include "toolkit/point_cloud.hpp"

namespace rgbd::sampling {

/// Concatenates views into one cloud in the world frame.
/// - A view still in its sensor frame is first brought to the world frame with its
///   world_from_sensor pose (InputError when it has none).
/// - The `view` (int32) property of each point = id of its source view. Exception: a view that
///   is itself a merge (sensor "merged") keeps its per-point view ids.
/// - The result has the union of all properties; a property missing in some view gets its
///   default value there (0 for flags and colours). A property name used with two different
///   types throws InputError. Normals are kept only if every non-empty view has them.
/// - Metadata: frame world, sensor "merged", id 0, no grid, no intrinsics, no pose; history
///   and extra comments = union of the views' lines, in order of first appearance.
/// The input views are consumed (their memory is reused).
PointCloud merge_views(std::vector<PointCloud>&& views_in_world_frame);

}  // namespace rgbd::sampling
