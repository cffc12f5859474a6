#include "algorithms/reconstruction/mesh_colour.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "algorithms/internal/spatial_order.hpp"

namespace rgbd::reconstruction::internal {
namespace {

/// Point flag of rgbd::frames::kUncoloured (depth_to_cloud.hpp): the colour camera did not see
/// the point; its colour was copied from the nearest seen point of its view, or is grey.
constexpr const char* kUncolouredFlag = "uncoloured";

/// The mesh's vertices in space order (internal::spatial_order).
std::vector<Mesh::Vertex_index> in_space_order(const Mesh& mesh) {
    std::vector<Mesh::Vertex_index> vertices(mesh.vertices().begin(), mesh.vertices().end());
    std::vector<Eigen::Vector3d> xyz;
    xyz.reserve(vertices.size());
    for (const auto v : vertices) xyz.push_back(to_eigen(mesh.point(v)));
    std::vector<Mesh::Vertex_index> out;
    out.reserve(vertices.size());
    for (const std::uint32_t i : rgbd::internal::spatial_order(xyz)) out.push_back(vertices[i]);
    return out;
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

void colorize(Mesh& mesh, const ColourSources& s, const ReconstructionOptions& o, double spacing) {
    const bool separate = s.separate;
    const rgbd::internal::PointSearch& all_tree = *s.all_tree;
    const auto& orig_tree = s.orig_tree;
    const std::vector<Rgb>& all_rgb = s.all_rgb;
    const std::vector<Rgb>& orig_rgb = s.orig_rgb;
    const double near = o.color_original_radius * spacing;
    const std::size_t k = static_cast<std::size_t>(o.color_k);

    std::vector<Mesh::Vertex_index> vertices = in_space_order(mesh);
    std::vector<MeshColor> result(vertices.size());
    const double floor_d = std::max(1e-3 * spacing, 1e-12);
    // Consecutive vertices (in space order) lie near each other, and so do their neighbours:
    // the largest distance from this vertex to the previous one's neighbours bounds its own
    // k-th nearest distance (any k points do), which keeps the searches of vertices far from
    // every point (a closure's) to a few cells. The neighbours, so the colours, are the same.
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, vertices.size(), 1024),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          std::vector<std::uint32_t> nn(k), last_all(k);
                          std::vector<double> sq(k);
                          bool have_all = false, have_orig = false;
                          std::uint32_t last_orig = 0;
                          for (std::size_t v = r.begin(); v != r.end(); ++v) {
                              const Eigen::Vector3d q = to_eigen(mesh.point(vertices[v]));
                              const rgbd::internal::PointSearch* tree = &all_tree;
                              const std::vector<Rgb>* rgb = &all_rgb;
                              if (separate) {
                                  std::uint32_t i;
                                  double d2;
                                  const double bound = rgbd::internal::knn_bound(
                                      s.orig_xyz, &last_orig, have_orig ? 1 : 0, q);
                                  have_orig = orig_tree->knn(q, 1, &i, &d2, bound) == 1;
                                  last_orig = i;
                                  if (have_orig && std::sqrt(d2) <= near) {
                                      tree = &*orig_tree;
                                      rgb = &orig_rgb;
                                  }
                              }
                              const bool all = tree == &all_tree;
                              const double bound = rgbd::internal::knn_bound(
                                  s.all_xyz, last_all.data(), all && have_all ? k : 0, q);
                              const std::size_t found =
                                  tree->knn(q, k, nn.data(), sq.data(), bound);
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
    VertexColorMap map = add_vertex_colors(mesh);
    for (std::size_t v = 0; v < vertices.size(); ++v) map[vertices[v]] = result[v];
}

}  // namespace rgbd::reconstruction::internal
