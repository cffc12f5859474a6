// TexturedMesh: a triangle mesh with per-corner texture coordinates into one or more texture
// atlases (rgbd-texture, docs/algorithms.md "Texturing"), or with vertex colours only. The form
// the OBJ / glTF writers and readers of io/textured_mesh_io.hpp exchange with the algorithms.
#pragma once

#include <Eigen/Core>
#include <array>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "toolkit/error.hpp"
#include "toolkit/mesh.hpp"
#include "toolkit/point_cloud.hpp"

namespace rgbd {

struct TexturedMesh {
    std::vector<Eigen::Vector3d> vertices;  ///< world frame, metres
    std::vector<std::array<int, 3>> faces;  ///< triangles, indices into `vertices`
    std::vector<Rgb> vertex_colors;         ///< one per vertex, or empty
    /// Texture coordinates in [0, 1], glTF convention: origin at the top-left corner of the
    /// atlas, u to the right, v down (OBJ files store 1 - v).
    std::vector<Eigen::Vector2f> uvs;
    std::vector<std::array<int, 3>> face_uvs;  ///< per face, indices into `uvs` (empty: untextured)
    std::vector<int> face_atlas;               ///< per face, index into `atlases`
    std::vector<cv::Mat> atlases;              ///< CV_8UC3, BGR
    /// The world's up direction (unit), e.g. sensors_up() of the colour cameras, or none. A .glb
    /// stores it as its root node's rotation taking it to glTF's +Y (io/textured_mesh_io.hpp);
    /// the vertices stay in the world frame.
    std::optional<Eigen::Vector3d> up;

    bool has_texture() const { return !atlases.empty() && face_uvs.size() == faces.size(); }
};

/// The triangles (faces with more than 3 vertices fanned) and vertex colours of `mesh`, without
/// texture. Throws InputError for a mesh without faces.
inline TexturedMesh untextured(const Mesh& mesh) {
    RGBD_CHECK(mesh.number_of_faces() > 0, "the mesh has no faces");
    TexturedMesh out;
    std::vector<int> index(mesh.num_vertices(), -1);
    const auto colors = vertex_colors(mesh);
    for (const auto v : mesh.vertices()) {
        index[v.idx()] = static_cast<int>(out.vertices.size());
        const auto& p = mesh.point(v);
        out.vertices.emplace_back(p.x(), p.y(), p.z());
        if (colors) {
            const MeshColor c = (*colors)[v];
            out.vertex_colors.push_back({c.red(), c.green(), c.blue()});
        }
    }
    for (const auto f : mesh.faces()) {
        std::vector<int> ids;
        const auto first = mesh.halfedge(f);
        auto h = first;
        do {
            ids.push_back(index[mesh.target(h).idx()]);
            h = mesh.next(h);
        } while (h != first);
        for (std::size_t j = 1; j + 1 < ids.size(); ++j)
            out.faces.push_back({ids[0], ids[j], ids[j + 1]});
    }
    return out;
}

}  // namespace rgbd
