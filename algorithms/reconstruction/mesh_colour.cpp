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
    const bool separate = s.separate;
    const rgbd::internal::PointSearch& all_tree = *s.all_tree;
    const auto& orig_tree = s.orig_tree;
    const std::vector<Rgb>& all_rgb = s.all_rgb;
    const std::vector<Rgb>& orig_rgb = s.orig_rgb;
    const double near = o.color_original_radius * spacing;
    const std::size_t k = static_cast<std::size_t>(o.color_k);
    std::vector<MeshColor> result(q.size());
    const double floor_d = std::max(1e-3 * spacing, 1e-12);
    // Consecutive positions (in space order) lie near each other, and so do their neighbours:
    // the largest distance from this position to the previous one's neighbours bounds its own
    // k-th nearest distance (any k points do), which keeps the searches of positions far from
    // every point (a closure's) to a few cells. The neighbours, so the colours, are the same.
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, q.size(), 1024),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          std::vector<std::uint32_t> nn(k), last_all(k);
                          std::vector<double> sq(k);
                          bool have_all = false, have_orig = false;
                          std::uint32_t last_orig = 0;
                          for (std::size_t v = r.begin(); v != r.end(); ++v) {
                              const Eigen::Vector3d& p = q[v];
                              const rgbd::internal::PointSearch* tree = &all_tree;
                              const std::vector<Rgb>* rgb = &all_rgb;
                              if (separate) {
                                  std::uint32_t i;
                                  double d2;
                                  const double bound = rgbd::internal::knn_bound(
                                      s.orig_xyz, &last_orig, have_orig ? 1 : 0, p);
                                  have_orig = orig_tree->knn(p, 1, &i, &d2, bound) == 1;
                                  last_orig = i;
                                  if (have_orig && std::sqrt(d2) <= near) {
                                      tree = &*orig_tree;
                                      rgb = &orig_rgb;
                                  }
                              }
                              const bool all = tree == &all_tree;
                              const double bound = rgbd::internal::knn_bound(
                                  s.all_xyz, last_all.data(), all && have_all ? k : 0, p);
                              const std::size_t found =
                                  tree->knn(p, k, nn.data(), sq.data(), bound);
                              have_all = all && found == k;
                              if (have_all) std::copy(nn.begin(), nn.end(), last_all.begin());
                              double w_sum = 0, rs = 0, gs = 0, bs = 0;
                              for (std::size_t j = 0; j < found; ++j) {
                                  const double d = std::max(std::sqrt(sq[j]), floor_d);
                                  const double w = 1.0 / (d * d);
                                  const Rgb& c = (*rgb)[nn[j]];
                                  w_sum += w;
                                  rs += w * c.r;
                                  gs += w * c.g;
                                  bs += w * c.b;
                              }
                              auto channel = [w_sum](double s) {
                                  return static_cast<unsigned char>(
                                      std::lround(std::clamp(s / w_sum, 0.0, 255.0)));
                              };
                              result[v] = found ? MeshColor(channel(rs), channel(gs), channel(bs))
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
    const auto uncoloured = cloud.flag(kUncolouredFlag);
    s.all_xyz.reserve(cloud.size());
    s.all_rgb.reserve(cloud.size());
    const bool flagged = synthetic.has_value() || uncoloured.has_value();
    for (auto idx : cloud.points) {
        const Eigen::Vector3d p = to_eigen(cloud.points.point(idx));
        s.all_xyz.push_back(p);
        s.all_rgb.push_back(colors.get(idx));
        if (flagged && (!synthetic || (*synthetic)[idx] == 0) &&
            (!uncoloured || (*uncoloured)[idx] == 0)) {
            s.orig_xyz.push_back(p);
            s.orig_rgb.push_back(colors.get(idx));
        }
    }
    // The measured points searched on their own only when some points are not measured (with
    // all of them measured, both searches would find the same neighbours).
    s.separate = !s.orig_xyz.empty() && s.orig_xyz.size() < s.all_xyz.size();
    // Cell grids, not kd-trees: millions of points on a dense sequence against the mesh's
    // vertices, and a kd-tree's build is sequential.
    s.all_tree.emplace(s.all_xyz);
    if (s.separate) s.orig_tree.emplace(s.orig_xyz);
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
