#include "algorithms/reconstruction/mesh_finishing.hpp"

#include <CGAL/Polygon_mesh_processing/border.h>
#include <CGAL/Polygon_mesh_processing/compute_normal.h>
#include <CGAL/Polygon_mesh_processing/connected_components.h>
#include <CGAL/Polygon_mesh_processing/fair.h>
#include <CGAL/Polygon_mesh_processing/refine.h>
#include <CGAL/Polygon_mesh_processing/repair.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Bounded_normal_change_placement.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/GarlandHeckbert_plane_policies.h>
#include <CGAL/Surface_mesh_simplification/edge_collapse.h>
#include <CGAL/boost/graph/Euler_operations.h>
#include <CGAL/boost/graph/helpers.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <iterator>
#include <vector>

#include "toolkit/report.hpp"

namespace rgbd::reconstruction::internal {

namespace PMP = CGAL::Polygon_mesh_processing;
namespace SMS = CGAL::Surface_mesh_simplification;

std::size_t drop_small_components(Mesh& mesh, double min_fraction) {
    if (mesh.number_of_faces() == 0 || min_fraction <= 0) return 0;
    auto fcc = mesh.add_property_map<Mesh::Face_index, std::size_t>("f:rgbd_cc", 0).first;
    const std::size_t count = PMP::connected_components(mesh, fcc);
    std::vector<std::size_t> sizes(count, 0);
    for (auto f : mesh.faces()) ++sizes[fcc[f]];
    mesh.remove_property_map(fcc);
    const std::size_t largest = *std::max_element(sizes.begin(), sizes.end());
    const auto threshold = static_cast<std::size_t>(std::ceil(min_fraction * largest));
    const std::size_t removed = PMP::keep_large_connected_components(mesh, threshold);
    PMP::remove_isolated_vertices(mesh);
    mesh.collect_garbage();
    return removed;
}

namespace {

using Halfedge = Mesh::Halfedge_index;

std::size_t loop_length(const Mesh& mesh, Halfedge h) {
    std::size_t n = 0;
    for (Halfedge x : CGAL::halfedges_around_face(h, mesh)) {
        (void)x;
        ++n;
    }
    return n;
}

/// Closes the loop of border halfedge h by one polygon, then a fan around its centroid, then
/// refines and fairs the fan (a smooth patch instead of a cone).
void fan_fill(Mesh& mesh, Halfedge h) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    std::size_t n = 0;
    for (Halfedge x : CGAL::halfedges_around_face(h, mesh)) {
        c += to_eigen(mesh.point(mesh.target(x)));
        ++n;
    }
    c /= static_cast<double>(n);
    CGAL::Euler::fill_hole(h, mesh);
    const Halfedge center = CGAL::Euler::add_center_vertex(h, mesh);
    const Mesh::Vertex_index apex = mesh.target(center);
    mesh.point(apex) = to_point(c);
    std::vector<Mesh::Face_index> fan;
    for (auto f : CGAL::faces_around_target(center, mesh))
        if (f != Mesh::null_face()) fan.push_back(f);
    std::vector<Mesh::Face_index> new_faces;
    std::vector<Mesh::Vertex_index> new_vertices{apex};
    PMP::refine(mesh, fan, std::back_inserter(new_faces), std::back_inserter(new_vertices),
                CGAL::parameters::density_control_factor(std::sqrt(2.0)));
    PMP::fair(mesh, new_vertices);
}

/// A loop that is planar and meets the surface around it at a crease (the faces along it are
/// steep to its plane, as at the cut base of a bust) is a cut: it gets a flat patch. Other
/// loops (a crown, a chin seen from nowhere) continue the surface smoothly: a faired patch.
bool is_planar_cut(const Mesh& mesh, Halfedge h) {
    std::vector<Eigen::Vector3d> loop;
    for (Halfedge x : CGAL::halfedges_around_face(h, mesh))
        loop.push_back(to_eigen(mesh.point(mesh.target(x))));
    if (loop.size() < 8) return false;
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (const auto& p : loop) c += p;
    c /= static_cast<double>(loop.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    double radius = 0;
    for (const auto& p : loop) {
        cov += (p - c) * (p - c).transpose();
        radius = std::max(radius, (p - c).norm());
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
    eig.computeDirect(cov);
    const Eigen::Vector3d n = eig.eigenvectors().col(0);
    double rms = 0;
    for (const auto& p : loop) rms += std::pow((p - c).dot(n), 2);
    rms = std::sqrt(rms / static_cast<double>(loop.size()));
    if (rms > 0.05 * radius) return false;
    double steep = 0;
    std::size_t count = 0;
    for (Halfedge x : CGAL::halfedges_around_face(h, mesh)) {
        const Mesh::Face_index f = mesh.face(mesh.opposite(x));
        if (f == Mesh::null_face()) continue;
        const Vector_3 fn = PMP::compute_face_normal(f, mesh);
        steep += std::abs(to_eigen(fn).dot(n));
        ++count;
    }
    return count > 0 && steep / static_cast<double>(count) < 0.5;
}

}  // namespace

Report close_holes(Mesh& mesh, std::size_t fair_max_edges) {
    Stopwatch watch;
    std::vector<Halfedge> borders;
    PMP::extract_boundary_cycles(mesh, std::back_inserter(borders));
    std::size_t faired = 0, refined = 0, flat = 0, fans = 0, largest = 0;
    const std::size_t faces_before = mesh.number_of_faces();
    for (Halfedge h : borders) {
        if (!mesh.is_border(h)) continue;  // closed by an earlier fill
        const std::size_t edges = loop_length(mesh, h);
        largest = std::max(largest, edges);
        std::vector<Mesh::Face_index> faces;
        std::vector<Mesh::Vertex_index> vertices;
        const auto np = CGAL::parameters::use_delaunay_triangulation(true)
                            .use_2d_constrained_delaunay_triangulation(true)
                            .do_not_use_cubic_algorithm(edges > 200);
        bool ok = false;
        if (is_planar_cut(mesh, h)) {
            PMP::triangulate_and_refine_hole(mesh, h, std::back_inserter(faces),
                                             std::back_inserter(vertices), np);
            ok = !faces.empty();
            if (ok) ++flat;
        } else if (edges <= fair_max_edges) {
            const auto result = PMP::triangulate_refine_and_fair_hole(
                mesh, h, std::back_inserter(faces), std::back_inserter(vertices), np);
            ok = !faces.empty();
            if (ok) ++faired;
            (void)result;
        } else {
            PMP::triangulate_and_refine_hole(mesh, h, std::back_inserter(faces),
                                             std::back_inserter(vertices), np);
            ok = !faces.empty();
            if (ok) ++refined;
        }
        if (!ok && mesh.is_border(h)) {
            fan_fill(mesh, h);
            ++fans;
        }
    }
    Report r;
    r["holes"] = borders.size();
    r["faired"] = faired;
    r["refined"] = refined;
    r["flat_cuts"] = flat;
    r["fans"] = fans;
    r["largest_hole_edges"] = largest;
    r["faces_added"] = mesh.number_of_faces() - faces_before;
    r["time_s"] = watch.seconds();
    return r;
}

namespace {

/// Stops the collapse once the mesh has at most `target` faces.
struct FaceBudget {
    const Mesh* mesh;
    std::size_t target;
    template <typename FT, typename Profile>
    bool operator()(const FT&, const Profile&, std::size_t, std::size_t) const {
        return mesh->number_of_faces() <= target;
    }
};

}  // namespace

Report simplify_to_faces(Mesh& mesh, std::size_t target_faces) {
    Stopwatch watch;
    Report r;
    r["faces_before"] = mesh.number_of_faces();
    std::size_t collapsed = 0;
    if (mesh.number_of_faces() > target_faces) {
        using Policies = SMS::GarlandHeckbert_plane_policies<Mesh, Kernel>;
        Policies policies(mesh);
        const SMS::Bounded_normal_change_placement<Policies::Get_placement> placement(
            policies.get_placement());
        collapsed = static_cast<std::size_t>(SMS::edge_collapse(
            mesh, FaceBudget{&mesh, target_faces},
            CGAL::parameters::get_cost(policies.get_cost()).get_placement(placement)));
        mesh.collect_garbage();
    }
    r["faces_after"] = mesh.number_of_faces();
    r["collapsed_edges"] = collapsed;
    r["time_s"] = watch.seconds();
    return r;
}

}  // namespace rgbd::reconstruction::internal
