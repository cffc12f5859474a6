// Single-file mesh and point-cloud I/O: PLY (first document), OFF, OBJ for meshes; PLY, XYZ
// (x y z [nx ny nz]), PCD (ascii, binary, binary_compressed) and OFF/OBJ vertices for clouds.
// Writers are atomic (temporary file, then rename) and pick the format by extension.
#pragma once

#include <filesystem>

#include "toolkit/mesh.hpp"
#include "toolkit/point_cloud.hpp"

namespace rgbd::io {

/// Reads a triangle mesh (.ply, .off, .obj; polygons are triangulated). Throws InputError
/// naming the file for a missing file, garbage, a truncated file, NaN coordinates, face
/// indices out of range, or a mesh without faces.
Mesh read_mesh(const std::filesystem::path& path);

/// Writes .ply (binary little-endian, vertex colours as red green blue uchar when present),
/// .off or .obj, atomically. `view` metadata goes into PLY comments when given.
void write_mesh(const std::filesystem::path& path, const Mesh& mesh,
                const ViewInfo* view = nullptr);

/// Reads a point cloud from .ply (first document), .xyz/.pwn, .pcd, or a mesh file's vertices.
PointCloud read_point_cloud(const std::filesystem::path& path);

/// Writes a point cloud as .ply (binary, all properties) or .xyz, atomically.
void write_point_cloud(const std::filesystem::path& path, const PointCloud& cloud);

}  // namespace rgbd::io
