// Textured mesh files (rgbd-texture, rgbd-reconstruct -o model.obj|glb, rgbd-eval --colour;
// docs/formats.md): Wavefront OBJ with its MTL and PNG atlases beside it, and glTF 2.0 binary
// (.glb) with the atlases embedded as PNG (written and read with tinygltf, Debian's
// libtinygltf-dev). Every file is written to a temporary file and renamed into place; the OBJ
// (the model itself) comes last, and a failure removes the companions already written, so no
// half-written model is left.
#pragma once

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

/// Writes `mesh` as .obj (+ .mtl + .png) or .glb by the extension. A mesh without texture is
/// written with vertex colours (OBJ "v x y z r g b", glTF COLOR_0). `comment` goes into the
/// OBJ header and the glTF asset's generator. Throws IoError naming the file (folder missing,
/// cannot write), InputError for another extension or an inconsistent mesh.
void write_textured_mesh(const std::filesystem::path& path, const TexturedMesh& mesh,
                         const std::string& comment = {});

/// Reads a .obj (with the MTL's map_Kd texture when it has one, and "v x y z r g b" vertex
/// colours), a .glb (first scene's meshes; node transforms are not applied: files written by
/// this toolkit have none), or any mesh read_mesh reads (.ply, .off: vertex colours).
/// Polygons are fanned into triangles. Throws InputError/IoError naming the file.
TexturedMesh read_textured_mesh(const std::filesystem::path& path);

}  // namespace rgbd::io
