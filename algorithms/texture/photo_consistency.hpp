// Rejection of photo-inconsistent views before the view selection (rgbd-texture,
// docs/algorithms.md "Texturing"): a simplified form of the photo-consistency check of Waechter,
// Moehrle and Goesele, "Let there be color!", ECCV 2014, §3.1. For every face seen by at least
// `min_views` cameras, the face's mean colour in each of them (four bilinear samples: the centre
// and the points a third of the way from it to the corners, after the camera's global gain and
// offset) is compared with the per-channel median of those colours; a camera whose colour lies
// farther than `max_levels` (Euclidean, BGR levels) from the median loses the face (its quality
// is set to 0): an occluder the depth test missed, a part that moved between frames, a specular
// highlight, or a pose error large enough to show another surface. The median is robust while
// fewer than half of the cameras are wrong (Waechter et al. use a mean-shift mode instead). The
// camera closest to the median always keeps the face. See also: view_selection.hpp.
#pragma once

#include <vector>

#include "algorithms/texture/colour_adjustment.hpp"
#include "algorithms/texture/view_selection.hpp"
#include "toolkit/report.hpp"

namespace rgbd::texture {

struct ConsistencyOptions {
    bool enabled = true;
    int min_views = 3;         ///< faces seen by fewer cameras are left alone (no majority)
    double max_levels = 25.0;  ///< largest distance of a camera's colour from the median, levels

    void check() const;
};

/// Sets quality(v, f) to 0 for the inconsistent cameras of each face (see the file comment).
/// `gains` as from adjust_colours (one per view). Report: faces checked, (view, face) pairs
/// rejected, per-view rejected counts. Returns the number of pairs rejected.
std::size_t reject_inconsistent_views(const render::RenderScene& scene,
                                      const std::vector<TextureView>& views,
                                      const std::vector<ColourGain>& gains,
                                      const ConsistencyOptions& options, FaceQuality& quality,
                                      Report& report);

}  // namespace rgbd::texture
