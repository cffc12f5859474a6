// Local seam levelling of a texture (rgbd-texture, docs/algorithms.md "Texturing"), after the
// global per-camera gain and offset of colour_adjustment.hpp: Waechter, Moehrle and Goesele,
// "Let there be color!", ECCV 2014, §4 (after Lempitsky and Ivanov, "Seamless mosaicing of
// image-based texture maps", CVPR 2007). Every chart gets an additive colour correction g per
// vertex and channel (a vertex on a seam has one value per chart touching it). With f the colour
// a chart's image shows at a seam vertex (the gain-adjusted image sampled along the seam edges
// at that vertex, one sample per image pixel of edge length, weighted by 1 - the distance to the
// vertex in units of the edge), the corrections minimise
//   sum over seam vertices and chart pairs (A, B) meeting there of (f_A + g_A - f_B - g_B)^2
//   + smoothness * sum over the edges inside each chart of (g_i - g_j)^2
//   + regularisation * sum of g^2,
// a sparse symmetric positive definite system (one matrix, three right-hand sides) solved by
// Eigen's SimplicialLDLT. The regularisation fixes each connected set of charts' common constant
// and keeps the corrections local, decaying into a chart over a few edges. Waechter et al. weigh
// the edge term by 1/lambda = 10 and have no regularisation; with many small charts (1,800 on
// the person sequence) that let the seam differences along chains of charts add up into
// corrections of 5-9 levels on average and lost 0.6-1.3 dB PSNR (smoothness 10, regularisation
// 1e-3). Smoothness 0.1 with regularisation 0.03 (the person: +0.6 dB over the photo-consistency
// alone, flat from 0.1 to 1 with the ratio kept) closes a step of 40 levels between two flat charts
// to 1.8 levels at the seam's vertices, 8 levels at the centres of the faces next to it, and leaves
// the colours ten faces away within 2 levels (tests/algorithms/texture/seam_levelling_test.cpp).
// Seam pairs whose colours differ by more than outlier_levels in a channel are left out (an
// occluder, not a brightness step). The corrections are interpolated over each face's texels
// (barycentric) when the atlas is written (add_chart_correction), and extended to the padding
// around the chart ring by ring, each texel the mean of its covered neighbours
// (algorithms/internal/ring_dilation.hpp, the dilation the atlas pads charts with).
#pragma once

#include <Eigen/Core>
#include <array>
#include <opencv2/core.hpp>
#include <unordered_map>
#include <vector>

#include "algorithms/texture/atlas.hpp"
#include "algorithms/texture/colour_adjustment.hpp"
#include "algorithms/texture/view_selection.hpp"
#include "toolkit/report.hpp"

namespace rgbd::texture {
struct LevellingOptions {
    bool enabled = true;
    double smoothness = 0.1;       ///< weight of the edge term inside a chart (seam term: 1)
    double regularisation = 0.03;  ///< weight of g^2 per unknown (keeps the corrections local)
    double outlier_levels = 60.0;  ///< seam pairs differing by more (any channel) are left out

    void check() const;
};

/// The corrections: for chart c, its vertices' additive BGR corrections (levels).
struct SeamCorrections {
    std::vector<std::unordered_map<int, Eigen::Vector3f>> chart_vertex;
};

/// Solves for the corrections of `charts` (as from make_charts over `adjacency`), sampling each
/// chart's view through gains[view]. Report: unknowns, seam vertices, seam terms, outliers, the
/// mean and largest absolute correction (levels) and the time.
SeamCorrections level_seams(const render::RenderScene& scene, const std::vector<TextureView>& views,
                            const std::vector<ColourGain>& gains, const std::vector<Chart>& charts,
                            const std::vector<std::array<int, 3>>& adjacency,
                            const LevellingOptions& options, Report& report);

/// Adds one chart's corrections to its rectangle `target` of the atlas (CV_8UC3, saturating):
/// `faces` the chart's triangles as vertex indices, `texel_of` each vertex's position in
/// `target` in texel units (texel (x, y) covers [x, x + 1) x [y, y + 1)), `correction` each
/// vertex's correction (BGR levels). Texels no face covers take the correction of the nearest
/// covered texels (up to `reach` texels away; beyond, the chart's mean correction).
void add_chart_correction(cv::Mat& target, const std::vector<std::array<int, 3>>& faces,
                          const std::unordered_map<int, Eigen::Vector2d>& texel_of,
                          const std::unordered_map<int, Eigen::Vector3f>& correction, int reach);

}  // namespace rgbd::texture
