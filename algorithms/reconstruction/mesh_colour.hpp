// Vertex colours of a reconstructed mesh (docs/algorithms.md, stage 8 colouring): each vertex
// takes the inverse-distance-squared mean colour of its k nearest coloured input points; the
// points the colour cameras observed (neither filled nor uncoloured) win where one lies within
// color_original_radius spacings, so that fill and copied colours do not tint observed surface.
// See also: algorithms/texture/ (textured models from the colour images).
#pragma once

#include <Eigen/Core>
#include <array>
#include <boost/container_hash/hash.hpp>
#include <cstdint>
#include <optional>
#include <unordered_map>
#include <vector>

#include "algorithms/internal/cell_grid.hpp"
#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/reconstruction/reconstruct_surface.hpp"
#include "toolkit/point_cloud.hpp"

namespace rgbd::reconstruction::internal {

/// The coloured points the mesh's colours come from, in two sets searched on their own: the
/// observed ones (coloured by a colour camera: measured points, and super-resolved ones flagged
/// `colour_pixel`, whose colour is their colour pixel's; not `uncoloured`, whose colour is a
/// copy from elsewhere or a grey fallback) and the others (the fill's and the uncoloured points:
/// a few thousand). The k nearest of all points are the
/// nearest k of the two sets' k nearest, so no search over all of them is built (one cell grid
/// of millions of points fewer). When no point is observed, or none is flagged, every point is
/// in the first set and `separate` is false.
struct ColourSources {
    std::vector<Eigen::Vector3d> observed_xyz, other_xyz;
    std::vector<Rgb> observed_rgb, other_rgb;
    bool separate = false;  ///< some points are observed and some are not
    std::optional<rgbd::internal::PointSearch> observed;
    std::optional<rgbd::internal::KdTree> others;
};

/// Fills `s` from the cloud's coloured points; false when the cloud has no colours. Independent
/// of the mesh: runs while the surface is reconstructed (cell-grid searches).
bool prepare_colours(const PointCloud& cloud, ColourSources& s);

/// Colours computed before the mesh exists, by exact position (the bits of the three
/// coordinates): the advancing front's vertices are its input points, so their colours can be
/// computed while the front runs.
class KnownColours {
public:
    using Key = std::array<std::uint64_t, 3>;
    /// The colour at exactly `p`, or null.
    const MeshColor* find(const Eigen::Vector3d& p) const;
    void insert(const Eigen::Vector3d& p, const MeshColor& c);
    std::size_t size() const { return by_position_.size(); }

private:
    std::unordered_map<Key, MeshColor, boost::hash<Key>> by_position_;
};

/// The colours colorize() gives vertices at the positions `xyz` (metres), keyed by position.
KnownColours colour_points(const std::vector<Eigen::Vector3d>& xyz, const ColourSources& s,
                           const ReconstructionOptions& o, double spacing);

/// IDW colours (weights 1 / d^2, o.color_k neighbours) of the mesh's vertices from the coloured
/// points of `s`, observed points first when one lies within o.color_original_radius x `spacing`
/// (metres); grey (128) when nothing is found. A vertex at a position of `known` takes the
/// colour found there (the same colour, computed earlier). Adds or overwrites the vertex colour
/// map.
void colorize(Mesh& mesh, const ColourSources& s, const ReconstructionOptions& o, double spacing,
              const KnownColours* known = nullptr);

}  // namespace rgbd::reconstruction::internal
