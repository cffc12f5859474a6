// The colour error of a model against calibrated colour images (rgbd-eval --colour,
// docs/method.md, evaluation): the model is rendered into every colour camera with the z-buffer
// rasteriser of algorithms/render/; at every pixel where the model's surface is seen, its colour
// (the texture, bilinear, at the perspective-correct texture coordinate; vertex colours,
// interpolated, when the model has no texture) is compared with the image. Pixels within
// `erode_px` of the model's silhouette (where a small geometric error swaps surface and
// background) and pixels seeing the surface more obliquely than acos(min_cos) are left out.
// PSNR = 10 log10(255^2 / MSE) over the three channels of all compared pixels.
#pragma once

#include <vector>

#include "algorithms/texture/view_selection.hpp"
#include "toolkit/report.hpp"
#include "toolkit/textured_mesh.hpp"

namespace rgbd::texture {

struct ColourErrorOptions {
    int erode_px = 2;      ///< pixels left out next to the silhouette
    double min_cos = 0.2;  ///< pixels seeing the surface more obliquely are left out

    void check() const;
};

/// Per view and overall: pixels compared, PSNR (dB), mean absolute error (levels), RMSE.
struct ColourError {
    std::size_t pixels = 0;
    double psnr_db = 0;
    double mae = 0;   ///< mean absolute error per channel, levels 0-255
    double rmse = 0;  ///< levels
    Report report;    ///< the above plus per-view rows
};

/// Compares `model` with every view. Throws InputError when the model has neither texture nor
/// vertex colours, or no pixel of any view sees it.
ColourError surface_colour_error(const TexturedMesh& model, const std::vector<TextureView>& views,
                                 const ColourErrorOptions& options = {});

}  // namespace rgbd::texture
