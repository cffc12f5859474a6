#include "algorithms/reconstruction/closure_carving.hpp"

#include <CGAL/Polygon_mesh_processing/compute_normal.h>
#include <CGAL/Polygon_mesh_processing/connected_components.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <unordered_map>

namespace rgbd::reconstruction::internal {

namespace PMP = CGAL::Polygon_mesh_processing;
using Halfedge = Mesh::Halfedge_index;

std::size_t orient_outward(Mesh& mesh) {
    auto component = mesh.add_property_map<Mesh::Face_index, std::size_t>("f:rgbd_orient", 0).first;
    const std::size_t count = PMP::connected_components(mesh, component);
    std::vector<double> volume(count, 0.0);
    std::vector<char> open(count, 0);
    for (auto f : mesh.faces()) {
        const Halfedge h = mesh.halfedge(f);
        const Eigen::Vector3d a = to_eigen(mesh.point(mesh.source(h)));
        const Eigen::Vector3d b = to_eigen(mesh.point(mesh.target(h)));
        const Eigen::Vector3d c = to_eigen(mesh.point(mesh.target(mesh.next(h))));
        volume[component[f]] += a.dot(b.cross(c)) / 6.0;
        for (Halfedge x : CGAL::halfedges_around_face(h, mesh))
            if (mesh.is_border(mesh.opposite(x))) open[component[f]] = 1;
    }
    std::size_t reversed = 0;
    for (std::size_t k = 0; k < count; ++k) {
        if (open[k] || !(volume[k] < 0)) continue;
        std::vector<Mesh::Face_index> faces;
        for (auto f : mesh.faces())
            if (component[f] == k) faces.push_back(f);
        PMP::reverse_face_orientations(faces, mesh);
        ++reversed;
    }
    mesh.remove_property_map(component);
    return reversed;
}

std::size_t carve_patch(Mesh& mesh, const std::vector<Mesh::Face_index>& faces,
                        const std::vector<Mesh::Vertex_index>& vertices,
                        const SeenEmpty& seen_empty, int max_steps) {
    if (faces.size() < 20 || vertices.empty()) return 0;
    double length = 0;
    std::size_t edges = 0;
    for (auto f : faces)
        for (Halfedge h : CGAL::halfedges_around_face(mesh.halfedge(f), mesh)) {
            length += (to_eigen(mesh.point(mesh.source(h))) - to_eigen(mesh.point(mesh.target(h))))
                          .norm();
            ++edges;
        }
    const double step = 0.5 * length / static_cast<double>(std::max<std::size_t>(edges, 1));
    const std::size_t n = vertices.size();
    std::unordered_map<std::uint32_t, std::uint32_t> index;
    for (std::size_t i = 0; i < n; ++i) index.emplace(std::uint32_t(vertices[i]), std::uint32_t(i));
    // Neighbours inside the patch (-1: a rim vertex, depth 0), and the rim's points.
    std::vector<std::vector<std::int64_t>> around(n);
    std::vector<Eigen::Vector3d> base(n), direction(n), rim;
    for (std::size_t i = 0; i < n; ++i) {
        base[i] = to_eigen(mesh.point(vertices[i]));
        direction[i] = to_eigen(PMP::compute_vertex_normal(vertices[i], mesh));
        for (auto w : CGAL::vertices_around_target(mesh.halfedge(vertices[i]), mesh)) {
            const auto it = index.find(std::uint32_t(w));
            if (it == index.end()) rim.push_back(to_eigen(mesh.point(w)));
            around[i].push_back(it == index.end() ? -1 : std::int64_t(it->second));
        }
    }
    // The deepest a vertex may go: half its distance to the rim (a slope of 27 degrees from
    // the rim), so that a patch is dented, never pushed through the object it closes.
    std::vector<double> deepest(n, 0.0);
    for (std::size_t i = 0; i < n; ++i) {
        double nearest = std::numeric_limits<double>::infinity();
        for (const auto& q : rim) nearest = std::min(nearest, (q - base[i]).squaredNorm());
        deepest[i] = rim.empty() ? 0.0 : 0.5 * std::sqrt(nearest);
    }
    std::vector<double> depth(n, 0.0), smoothed(n);
    std::vector<char> empty(n, 0), moved(n, 0);
    for (int k = 0; k < max_steps; ++k) {
        tbb::parallel_for(std::size_t(0), n, [&](std::size_t i) {
            empty[i] = depth[i] < deepest[i] && direction[i].allFinite() &&
                       direction[i].squaredNorm() > 0.5 &&
                       seen_empty(base[i] - depth[i] * direction[i], direction[i]);
        });
        if (std::find(empty.begin(), empty.end(), 1) == empty.end()) break;
        for (std::size_t i = 0; i < n; ++i)
            if (empty[i]) depth[i] += step, moved[i] = 1;
        // Smoothed over the patch (the rim holds at depth 0), never below the deepest.
        for (std::size_t i = 0; i < n; ++i) {
            if (around[i].empty()) {
                smoothed[i] = depth[i];
                continue;
            }
            double sum = 0;
            for (auto j : around[i]) sum += j < 0 ? 0.0 : depth[std::size_t(j)];
            smoothed[i] = std::min(
                deepest[i], 0.5 * depth[i] + 0.5 * sum / static_cast<double>(around[i].size()));
        }
        depth.swap(smoothed);
    }
    for (std::size_t i = 0; i < n; ++i)
        if (depth[i] > 0 && direction[i].allFinite())
            mesh.point(vertices[i]) = to_point(base[i] - depth[i] * direction[i]);
    return static_cast<std::size_t>(std::count(moved.begin(), moved.end(), 1));
}

namespace {

/// Distance from a along unit direction d (2D) to the nearest crossing of the closed polygon
/// `loop` (2D), without the two edges at its vertex i; +inf when there is none.
double ray_to_polygon(const std::vector<Eigen::Vector2d>& loop, std::size_t i,
                      const Eigen::Vector2d& a, const Eigen::Vector2d& d) {
    const std::size_t n = loop.size();
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < n; ++k) {
        const std::size_t l = (k + 1) % n;
        if (k == i || l == i) continue;
        const Eigen::Vector2d e = loop[l] - loop[k];
        const double den = d.x() * e.y() - d.y() * e.x();
        if (std::abs(den) < 1e-15) continue;
        const Eigen::Vector2d w = loop[k] - a;
        const double t = (w.x() * e.y() - w.y() * e.x()) / den;              // along d
        const double u = (w.x() * d.y() - w.y() * d.x()) / den;              // along e
        if (t > 0 && u >= -1e-9 && u <= 1 + 1e-9) best = std::min(best, t);  // vertices too
    }
    return best;
}

/// The pairs (i, j) of edges (edge k joins vertices k and k + 1) of the closed polygon `loop`
/// (2D) that do not share a vertex and cross properly (each edge's ends strictly on both sides of
/// the other's line), into `out`.
void crossing_edges(const std::vector<Eigen::Vector2d>& loop,
                    std::vector<std::pair<std::size_t, std::size_t>>& out) {
    const std::size_t n = loop.size();
    const auto side = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                         const Eigen::Vector2d& c) {
        return (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
    };
    for (std::size_t i = 0; i < n; ++i) {
        const Eigen::Vector2d &a = loop[i], &b = loop[(i + 1) % n];
        for (std::size_t j = i + 2; j < n; ++j) {
            if (i == 0 && j == n - 1) continue;  // neighbours through the first vertex
            const Eigen::Vector2d &c = loop[j], &d = loop[(j + 1) % n];
            if (side(a, b, c) * side(a, b, d) < 0 && side(c, d, a) * side(c, d, b) < 0)
                out.emplace_back(i, j);
        }
    }
}

/// The feet of carve_walls (`foot` moved inward by `depth` along `outward`), made to cross each
/// other no more often than the unmoved feet do (the plane through `point` with axes `a`, `b`; `w`
/// the chord's reach, `step` the carving step).
std::vector<Eigen::Vector3d> untangled_feet(const std::vector<Eigen::Vector3d>& foot,
                                            const std::vector<Eigen::Vector3d>& outward,
                                            std::vector<double> depth, const Eigen::Vector3d& point,
                                            const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                            std::size_t w, double step) {
    // The base is capped as a polygon. Feet moved inward round a convex bend converge and cross,
    // leaving a small loop (a swallowtail, as on any inward offset curve): the feet of its
    // shorter side (at most a quarter of the loop) are put on the chord that cuts it off, round
    // after round, until the feet cross no more often than the rim's own ragged loop did. If that
    // fails within 8 rounds, the displacements round the crossing edges are halved instead,
    // round after round (every displacement dropped after 8 more).
    const std::size_t n = foot.size();
    const auto foot_at = [&](std::size_t i, double d) { return foot[i] - d * outward[i]; };
    std::vector<Eigen::Vector3d> placed(n);
    std::vector<Eigen::Vector2d> flat(n);
    std::vector<std::pair<std::size_t, std::size_t>> crossed;
    const auto cross_count = [&] {
        for (std::size_t i = 0; i < n; ++i) {
            const Eigen::Vector3d f = placed[i] - point;
            flat[i] = {f.dot(a), f.dot(b)};
        }
        crossed.clear();
        crossing_edges(flat, crossed);
        return crossed.size();
    };
    const auto place = [&](const std::vector<double>& d) {
        for (std::size_t i = 0; i < n; ++i) placed[i] = foot_at(i, d[i]);
    };
    place(std::vector<double>(n, 0.0));
    const std::size_t allowed = cross_count();
    place(depth);
    bool untangled = cross_count() <= allowed;
    for (int round = 0; !untangled && round < 8; ++round) {
        std::vector<char> taken(n, 0);
        for (const auto& [i, j] : crossed) {
            // Edges i and j cross: the feet i+1..j form one side, j+1..i the other.
            const std::size_t inner = j - i, outer = n - inner;
            const bool first = inner <= outer;
            const std::size_t from = first ? i : j, count = first ? inner : outer;
            if (count > n / 4) continue;  // not a swallowtail
            bool free = true;
            for (std::size_t k = 0; k <= count + 1 && free; ++k) free = !taken[(from + k) % n];
            if (!free) continue;
            const Eigen::Vector3d start = placed[from], end = placed[(from + count + 1) % n];
            if ((end - start).norm() < 1e-3 * step) continue;  // no chord: feet would coincide
            for (std::size_t k = 1; k <= count; ++k)
                placed[(from + k) % n] = start + (double(k) / double(count + 1)) * (end - start);
            for (std::size_t k = 0; k <= count + 1; ++k) taken[(from + k) % n] = 1;
        }
        untangled = cross_count() <= allowed;
    }
    for (int round = 0; !untangled; ++round) {
        if (round == 0) {
            place(depth);
            cross_count();
        }
        if (round == 8) {
            std::fill(depth.begin(), depth.end(), 0.0);
            place(depth);
            break;
        }
        std::vector<char> halve(n, 0);
        for (const auto& [i, j] : crossed)
            for (const std::size_t e : {i, j})
                for (std::size_t k = 0; k <= 2 * w + 1; ++k) halve[(e + n - w + k) % n] = 1;
        for (std::size_t i = 0; i < n; ++i)
            if (halve[i]) depth[i] *= 0.5;
        place(depth);
        untangled = cross_count() <= allowed;
    }
    return placed;
}

}  // namespace

std::size_t carve_walls(Mesh& mesh,
                        const std::vector<std::pair<Mesh::Vertex_index, Mesh::Vertex_index>>& walls,
                        const Eigen::Vector3d& point, const Eigen::Vector3d& down,
                        const SeenEmpty& seen_empty, int max_steps) {
    const std::size_t n = walls.size();
    if (n < 8 || !seen_empty || max_steps <= 0) return 0;
    // The base plane's frame: normal u (up), axes a and b in it.
    const Eigen::Vector3d u = -down.normalized();
    const Eigen::Vector3d seed =
        std::abs(u.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
    const Eigen::Vector3d a = (seed - seed.dot(u) * u).normalized(), b = u.cross(a);
    std::vector<Eigen::Vector3d> top(n), foot(n);
    std::vector<Eigen::Vector2d> loop(n);
    double length = 0, area = 0;
    for (std::size_t i = 0; i < n; ++i) {
        top[i] = to_eigen(mesh.point(walls[i].first));
        foot[i] = to_eigen(mesh.point(walls[i].second));
        loop[i] = {(top[i] - point).dot(a), (top[i] - point).dot(b)};
    }
    for (std::size_t i = 0; i < n; ++i) {
        const std::size_t j = (i + 1) % n;
        length += (top[j] - top[i]).norm();
        area += loop[i].x() * loop[j].y() - loop[j].x() * loop[i].y();
    }
    const double step = 0.5 * length / static_cast<double>(n);
    if (!(step > 0) || area == 0) return 0;
    // Outward in the plane: the loop's edges turned a right angle away from its inside (the
    // sign of its area about u), summed over the w edges on each side of a vertex (the chord
    // from w vertices before it to w after, turned): a ragged rim's own edges point every way,
    // and feet moved along them crossed each other (the bear in a room: 140 crossings, the rim
    // 4).
    const double side = area > 0 ? 1.0 : -1.0;
    const std::size_t w = std::clamp<std::size_t>(n / 16, 2, 8);
    std::vector<Eigen::Vector3d> outward(n, Eigen::Vector3d::Zero());
    std::vector<double> deepest(n, 0.0);
    for (std::size_t i = 0; i < n; ++i) {
        const Eigen::Vector2d chord = loop[(i + w) % n] - loop[(i + n - w) % n];
        Eigen::Vector2d o(chord.y(), -chord.x());
        if (o.squaredNorm() < 1e-24) continue;
        o = side * o.normalized();
        outward[i] = o.x() * a + o.y() * b;
        const double across = ray_to_polygon(loop, i, loop[i], -o);
        deepest[i] = std::isfinite(across) ? 0.4 * across : 0.0;
    }
    // Round a convex bend the feet moved inward converge: those w vertices apart meet after a
    // displacement of about their distance over their normals' difference (the bend's radius);
    // no foot goes beyond 0.7 of it (a leg's rounded end).
    for (std::size_t i = 0; i < n; ++i) {
        const std::size_t j0 = (i + n - w) % n, j1 = (i + w) % n;
        const Eigen::Vector3d apart = (top[j1] - top[j0]) - (top[j1] - top[j0]).dot(u) * u;
        const Eigen::Vector3d turn = outward[j1] - outward[j0];
        if (apart.dot(turn) > 0 && turn.norm() > 1e-9)
            deepest[i] = std::min(deepest[i], 0.7 * apart.norm() / turn.norm());
    }
    std::vector<double> depth(n, 0.0), smoothed(n);
    std::vector<char> empty(n, 0);
    const auto foot_at = [&](std::size_t i, double d) { return foot[i] - d * outward[i]; };
    for (int k = 0; k < max_steps; ++k) {
        tbb::parallel_for(std::size_t(0), n, [&](std::size_t i) {
            empty[i] = 0;
            if (depth[i] + step > deepest[i]) return;
            const Eigen::Vector3d f = foot_at(i, depth[i]), wall = f - top[i];
            if (wall.squaredNorm() < 1e-18) return;
            const Eigen::Vector3d along = wall.normalized();
            Eigen::Vector3d normal = outward[i] - outward[i].dot(along) * along;
            if (normal.squaredNorm() < 1e-18) return;
            normal.normalize();
            for (const double t : {1.0 / 3.0, 2.0 / 3.0})
                if (seen_empty(top[i] + t * wall, normal)) {
                    empty[i] = 1;
                    return;
                }
        });
        if (std::find(empty.begin(), empty.end(), 1) == empty.end()) break;
        for (std::size_t i = 0; i < n; ++i)
            if (empty[i]) depth[i] += step;
        for (std::size_t i = 0; i < n; ++i)
            smoothed[i] = std::min(
                deepest[i], 0.5 * depth[i] + 0.25 * (depth[(i + n - 1) % n] + depth[(i + 1) % n]));
        depth.swap(smoothed);
    }
    const std::vector<Eigen::Vector3d> placed =
        untangled_feet(foot, outward, depth, point, a, b, w, step);
    std::size_t count = 0;
    for (std::size_t i = 0; i < n; ++i)
        if ((placed[i] - foot[i]).squaredNorm() > 1e-18) {
            mesh.point(walls[i].second) = to_point(placed[i]);
            ++count;
        }
    return count;
}

}  // namespace rgbd::reconstruction::internal
