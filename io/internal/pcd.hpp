// PCD point clouds (PCL's format: ascii, binary, binary_compressed with LZF), read by
// io::read_point_cloud. See io/mesh_io.hpp.
#pragma once

#include <filesystem>

#include "toolkit/point_cloud.hpp"

namespace rgbd::io::internal {

/// Reads a .pcd file: x y z, optional normal_x/y/z, rgb/rgba packed colour; organised clouds
/// keep their pixel index. Throws InputError naming the file for bad or truncated input.
PointCloud read_pcd(const std::filesystem::path& path);

}  // namespace rgbd::io::internal
