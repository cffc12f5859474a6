#include "algorithms/reconstruction/mesh_colour.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "algorithms/internal/spatial_order.hpp"

namespace rgbd::reconstruction::internal {
namespace {

/// Point flag of rgbd::frames::kUncoloured (depth_to_cloud.hpp): the colour camera did not see
/// the point; its colour was copied from the nearest seen point of its view, or is grey.
constexpr const char* kUncolouredFlag = "uncoloured";

/// The key of an exact position: the bits of its coordinates.
KnownColours::Key position_key(const Eigen::Vector3d& p) {
    KnownColours::Key k;
    for (int i = 0; i < 3; ++i) std::memcpy(&k[i], &p[i], sizeof(double));
    return k;
}

/// IDW colours of the positions `q`, which lie in space order (internal::spatial_order):
/// colorize()'s rule, one colour per position.
std::vector<MeshColor> idw_colours(const std::vector<Eigen::Vector3d>& q, const ColourSources& s,
                                   const ReconstructionOptions& o, double spacing) {
    const double near = o.color_original_radius * spacing;
    const std::size_t k = static_cast<std::size_t>(o.color_k);
    std::vector<MeshColor> result(q.size());
    const double floor_d = std::max(1e-3 * spacing, 1e-12);
    // Consecutive positions (in space order) lie near each other, and so do their neighbours:
    // the largest distance from this position to the previous one's observed neighbours bounds
    // its own k-th nearest observed distance (any k points do), which keeps the searches of
    // positions far from every point (a closure's) to a few cells. The neighbours, so the
    // colours, are the same.
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, q.size(), 1024),
        [&](const tbb::blocked_range<std::size_t>& r) {
            std::vector<std::uint32_t> nn(k), last(k), other_nn(k);
            std::vector<double> sq(k), other_sq(k);
            bool have_last = false;
            for (std::size_t v = r.begin(); v != r.end(); ++v) {
                const Eigen::Vector3d& p = q[v];
                const double bound =
                    rgbd::internal::knn_bound(s.observed_xyz, last.data(), have_last ? k : 0, p);
                const std::size_t found = s.observed->knn(p, k, nn.data(), sq.data(), bound);
                have_last = found == k;
                if (have_last) std::copy(nn.begin(), nn.end(), last.begin());
                // The observed neighbours alone when one lies within the radius; otherwise the
                // k nearest of all points: both sets' nearest merged by distance.
                const bool observed_near = found > 0 && std::sqrt(sq[0]) <= near;
                const std::size_t other_found =
                    s.separate && !observed_near
                        ? s.others->knn(p, k, other_nn.data(), other_sq.data())
                        : 0;
                double w_sum = 0, rs = 0, gs = 0, bs = 0;
                std::size_t i = 0, j = 0;
                for (std::size_t taken = 0; taken < k && (i < found || j < other_found); ++taken) {
                    const bool from_observed =
                        j >= other_found || (i < found && sq[i] <= other_sq[j]);
                    const double d2 = from_observed ? sq[i] : other_sq[j];
                    const Rgb& c =
                        from_observed ? s.observed_rgb[nn[i++]] : s.other_rgb[other_nn[j++]];
                    const double d = std::max(std::sqrt(d2), floor_d);
                    const double w = 1.0 / (d * d);
                    w_sum += w;
                    rs += w * c.r;
                    gs += w * c.g;
                    bs += w * c.b;
                }
                auto channel = [w_sum](double s) {
                    return static_cast<unsigned char>(
                        std::lround(std::clamp(s / w_sum, 0.0, 255.0)));
                };
                result[v] = w_sum > 0 ? MeshColor(channel(rs), channel(gs), channel(bs))
                                      : MeshColor(128, 128, 128);
            }
        });
    return result;
}

}  // namespace

bool prepare_colours(const PointCloud& cloud, ColourSources& s) {
    if (!cloud.has_colors()) return false;
    const auto colors = cloud.colors();
    const auto synthetic = cloud.flag(prop::kSynthetic);
    const auto colour_pixel = cloud.flag(prop::kColourPixel);
    const auto uncoloured = cloud.flag(kUncolouredFlag);
    s.observed_xyz.reserve(cloud.size());
    s.observed_rgb.reserve(cloud.size());
    for (auto idx : cloud.points) {
        // Whether the colour is one a colour camera saw: a measured point's (unless
        // uncoloured) and a super-resolved one's (colour_pixel: its own colour pixel's); not the
        // colours a fill or a stand contact invents.
        const bool seen_colour =
            !synthetic || (*synthetic)[idx] == 0 || (colour_pixel && (*colour_pixel)[idx] != 0);
        const bool observed = seen_colour && (!uncoloured || (*uncoloured)[idx] == 0);
        (observed ? s.observed_xyz : s.other_xyz).push_back(to_eigen(cloud.points.point(idx)));
        (observed ? s.observed_rgb : s.other_rgb).push_back(colors.get(idx));
    }
    // No point observed: every point is in the first set (the others' order kept).
    if (s.observed_xyz.empty()) {
        s.observed_xyz.swap(s.other_xyz);
        s.observed_rgb.swap(s.other_rgb);
    }
    s.separate = !s.other_xyz.empty();
    // A cell grid for the millions of observed points (searched against the mesh's vertices;
    // a kd-tree's build is sequential), a kd-tree for the few others.
    s.observed.emplace(s.observed_xyz);
    if (s.separate) s.others.emplace(s.other_xyz);
    return true;
}

const MeshColor* KnownColours::find(const Eigen::Vector3d& p) const {
    const auto it = by_position_.find(position_key(p));
    return it == by_position_.end() ? nullptr : &it->second;
}

void KnownColours::insert(const Eigen::Vector3d& p, const MeshColor& c) {
    by_position_.emplace(position_key(p), c);
}

KnownColours colour_points(const std::vector<Eigen::Vector3d>& xyz, const ColourSources& s,
                           const ReconstructionOptions& o, double spacing) {
    std::vector<Eigen::Vector3d> q;
    q.reserve(xyz.size());
    for (const std::uint32_t i : rgbd::internal::spatial_order(xyz)) q.push_back(xyz[i]);
    const std::vector<MeshColor> colours = idw_colours(q, s, o, spacing);
    KnownColours known;
    for (std::size_t i = 0; i < q.size(); ++i) known.insert(q[i], colours[i]);
    return known;
}

void colorize(Mesh& mesh, const ColourSources& s, const ReconstructionOptions& o, double spacing,
              const KnownColours* known) {
    // The vertices in space order; those at a known position take its colour, the others are
    // searched (still in space order).
    const std::vector<Mesh::Vertex_index> vertices(mesh.vertices().begin(), mesh.vertices().end());
    std::vector<Eigen::Vector3d> xyz;
    xyz.reserve(vertices.size());
    for (const auto v : vertices) xyz.push_back(to_eigen(mesh.point(v)));
    VertexColorMap map = add_vertex_colors(mesh);
    std::vector<Mesh::Vertex_index> unknown;
    std::vector<Eigen::Vector3d> q;
    for (const std::uint32_t i : rgbd::internal::spatial_order(xyz)) {
        const MeshColor* c = known ? known->find(xyz[i]) : nullptr;
        if (c) {
            map[vertices[i]] = *c;
        } else {
            unknown.push_back(vertices[i]);
            q.push_back(xyz[i]);
        }
    }
    const std::vector<MeshColor> colours = idw_colours(q, s, o, spacing);
    for (std::size_t i = 0; i < unknown.size(); ++i) map[unknown[i]] = colours[i];
}

}  // namespace rgbd::reconstruction::internal
