// Exemplar-based colour inpainting (docs/algorithms.md §12): Criminisi, Perez, Toyama, "Region
// filling and object removal by exemplar-based image inpainting", IEEE TIP 2004. Texture stays
// texture (stripes, checks, hair strands), where Telea's fast marching blurs it.
// Repeat until the hole is empty: on the fill front, priority P(p) = C(p) D(p) with the
// confidence C(p) = sum of C(q) over the known pixels q of p's patch / |patch| (known pixels
// start at 1, hole pixels at 0) and the data term D(p) = |isophote(p) . n_p| / 255 (isophote =
// the strongest CIELab-L gradient among the patch's known pixels, rotated 90 degrees; n_p = the
// front's normal); the highest-priority patch (default 9 x 9) is filled from the source patch
// that minimises the squared CIELab differences over the target patch's known pixels; its
// missing pixels are copied and take the confidence C(p). The paper's source patches are made
// entirely of source pixels; in a sparsely known image (the cylinder of a bust, pixels of 1.5
// spacings) those are rare and far away, so a partial source patch is accepted too [M] when it
// holds every pixel to copy and at least half of the pixels to compare (mean squared
// difference over the pixels compared). Max Planck with 8 holes cut (measure_fill.py, smooth
// procedural colour): complete patches only put the large-hole points 30-66 levels off,
// partial ones 3-23 (Telea: 1-6; a smooth colour ramp is Telea's best case).
// The source patches are searched in a window 4 x the bounding box of the hole component being
// filled [M] (the whole image when that window holds none), in parallel (TBB). When no
// complete source patch fits in the image (a thin band of known pixels), the patch shrinks by
// 2 pixels until one does (down to 3 x 3) [M].
// Used by large_holes.cpp for the cylinder colour image and the head top's.
#pragma once

#include <opencv2/core.hpp>

namespace rgbd::holes {

struct ExemplarOptions {
    int patch = 9;               ///< patch side, pixels (odd, >= 3)
    double search_window = 4.0;  ///< search window side, multiple of the hole component's box
    void check() const;
};

struct ExemplarStats {
    int patches = 0;         ///< patches copied
    int filled = 0;          ///< pixels filled from exemplars
    int window_widened = 0;  ///< patches whose window held no source patch (image searched)
    int unfilled = 0;        ///< pixels left (no complete source patch in the image at all)
    int patch = 0;           ///< patch side used (smaller than asked when none fitted)
};

/// Fills the non-zero pixels of `target` (CV_8U) in `rgb` (CV_8UC3, any channel order whose
/// first channel is red; RGB as the toolkit stores colour) from patches made entirely of the
/// non-zero pixels of `source` (CV_8U, disjoint from target). Pixels in neither mask are never
/// read nor written. Pixels left when the image holds no complete 3 x 3 source patch keep
/// their value and are counted in `unfilled`. InputError for mismatched or wrongly typed images.
ExemplarStats exemplar_inpaint(cv::Mat& rgb, const cv::Mat& target, const cv::Mat& source,
                               const ExemplarOptions& options = {});

namespace detail {

/// CIE 1976 L*a*b* of an 8-bit sRGB colour (D65 white), as OpenCV's cv::COLOR_RGB2Lab of the
/// colour scaled to [0, 1] computes it (L in [0, 100]): the sRGB transfer curve undone exactly
/// (a table of the 256 levels), the sRGB-to-XYZ matrix over the white point, then the cube-root
/// law with its linear segment below (6/29)^3. OpenCV builds its Lab tables on first use with
/// software floating point, 0.1 s of one core in every process that fills a hole.
cv::Vec3f srgb_to_lab(const cv::Vec3b& rgb);

}  // namespace detail

}  // namespace rgbd::holes
