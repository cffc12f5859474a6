// Charts and texture atlas (rgbd-texture, docs/algorithms.md "Texturing"): the faces that share
// a view and an edge form a chart; each chart's texture is the rectangle of its colour image
// around the chart's projection plus padding, cut from the colour-adjusted image; the texels
// outside the chart's faces are then refilled from its border texels (pad_from_chart), so that
// bilinear lookups and mip-mapping near the chart's border read the chart's own colours, never
// a neighbouring chart's nor the background beyond the chart's silhouette; packed into power-of-two
// atlases by shelf packing (charts sorted by height; Jylanki, "A thousand ways to pack the bin",
// 2010, SHELF-NF). The texture coordinates of a chart's corners are their projections into its
// image. When the charts do not fit into one atlas of at most max_size x max_size texels, the
// charts' texel size is scaled down until they do (at most down to min_scale; then further atlases
// are opened). Faces no camera sees get a flat colour: a small cell of the atlas filled with the
// mean of their vertices' colours; those colours are quantised (1, 2, 4, ... levels per channel,
// the finest step that needs at most max_flat_cells cells; each cell holds the mean colour of its
// faces), so that a large unseen area of smoothly varying colour does not fill the atlas with
// thousands of one-colour cells.
#pragma once

#include <array>
#include <vector>

#include "algorithms/texture/colour_adjustment.hpp"
#include "algorithms/texture/view_selection.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/report.hpp"
#include "toolkit/textured_mesh.hpp"

namespace rgbd::texture {

struct AtlasOptions {
    int max_size = 8192;        ///< largest atlas side, texels (a power of two, 64 .. 16384)
    int padding_px = 2;         ///< image pixels kept around each chart's projection
    double scale = 1.0;         ///< texels per colour-image pixel (<= 1; lowered to fit max_size)
    double min_scale = 0.5;     ///< lowest automatic scale; below it charts go to more atlases
    int flat_cell_px = 4;       ///< side of a flat-colour cell (faces no camera sees)
    int max_flat_cells = 2048;  ///< at most this many flat cells (colours quantised to fit)
    /// Fill the texels around each chart's faces (padding_px + 2 rings) from the chart's own
    /// border texels, not from the image's pixels beyond the faces (the background where the
    /// chart meets its silhouette in its image).
    bool pad_from_chart = true;

    void check() const;
};

/// A chart: connected faces with the same view.
struct Chart {
    int view = -1;
    std::vector<int> faces;
};

/// Connected components of faces with the same label (faces with label -1 are in no chart),
/// in order of their first face.
std::vector<Chart> make_charts(const std::vector<int>& label,
                               const std::vector<std::array<int, 3>>& adjacency);

struct SeamCorrections;  // seam_levelling.hpp

/// Builds the textured mesh: the scene's vertices and triangles, the charts' textures (each
/// view's image adjusted by gains[view], then, with `seams`, each chart's local corrections
/// added over its texels, see seam_levelling.hpp) and flat cells for the faces of no chart,
/// coloured `flat_colour[face]` (quantised to at most max_flat_cells colours). Report: charts,
/// atlases, atlas sizes, scale, texels used, flat faces, flat cells and the colour quantum.
TexturedMesh build_atlas(const render::RenderScene& scene, const std::vector<TextureView>& views,
                         const std::vector<Chart>& charts, const std::vector<ColourGain>& gains,
                         const std::vector<Rgb>& flat_colour, const AtlasOptions& options,
                         Report& report, const SeamCorrections* seams = nullptr);

}  // namespace rgbd::texture
