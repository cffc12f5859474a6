// Textured mesh files (rgbd-texture, rgbd-reconstruct -o model.obj|glb, rgbd-eval --colour;
// docs/formats.md): Wavefront OBJ with its MTL and PNG atlases beside it, and glTF 2.0 binary
// (.glb) with the atlases embedded as PNG (written and read with tinygltf, Debian's
// libtinygltf-dev). Every file is written to a temporary file and renamed into place; the OBJ
// (the model itself) comes last, and a failure removes the companions already written, so no
// half-written model is left.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "toolkit/textured_mesh.hpp"

namespace rgbd::io {

/// True for the extensions write_textured_mesh writes (.obj, .glb; case-insensitive).
bool is_textured_format(const std::filesystem::path& path);

/// Files write_textured_mesh(path, mesh) writes: path, plus for .obj the MTL (path with .mtl)
/// and one PNG per atlas (path with .png, or _N.png for several atlases).
std::vector<std::filesystem::path> textured_mesh_files(const std::filesystem::path& path,
                                                       const TexturedMesh& mesh);

/// The rotation a .glb's root node applies when the mesh has an `up`: the smallest rotation
/// taking `up` (any length, non-zero) to glTF's +Y ("up" in the glTF 2.0 specification, section
/// 3.4), so that a viewer shows the model upright; +Z up becomes (x, z, -y), a turn of -90 deg
/// about x. Throws InputError for a zero or non-finite `up`.
Eigen::Matrix3d gltf_up_rotation(const Eigen::Vector3d& up);

/// Writes `mesh` as .obj (+ .mtl + .png) or .glb by the extension; a .glb of a mesh with `up`
/// gets a root node matrix of gltf_up_rotation(up) (the OBJ has no place for it). A mesh without
/// texture is written with vertex colours (OBJ "v x y z r g b", glTF COLOR_0). `comment` goes into
/// the OBJ header and the glTF asset's generator. Throws IoError naming the file (folder missing,
/// cannot write), InputError for another extension or an inconsistent mesh.
void write_textured_mesh(const std::filesystem::path& path, const TexturedMesh& mesh,
                         const std::string& comment = {});

/// Reads a .obj (with the MTL's map_Kd texture when it has one, and "v x y z r g b" vertex
/// colours), a .glb (first scene's meshes, vertices as stored: node transforms are not applied;
/// a root node whose transform is a rotation sets `up` to the direction it takes to +Y, the
/// inverse of what write_textured_mesh stores), or any mesh read_mesh reads (.ply, .off: vertex
/// colours).
/// Polygons are fanned into triangles. Throws InputError/IoError naming the file.
TexturedMesh read_textured_mesh(const std::filesystem::path& path);

}  // namespace rgbd::io
