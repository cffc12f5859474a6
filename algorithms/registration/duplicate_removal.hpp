// Colour-based duplicate removal when aligned views are merged (docs/algorithms.md §6 step 6, the
// thesis's "colour-based duplicate removal"): views are added in order; a point with an earlier
// point within r_dup = radius_spacing * ŝ is a duplicate when their colours agree (CIELab
// Delta E76 <= max_delta_e) and is dropped, keeping the density of overlaps that of one view;
// when the colours disagree, the better observed of the two (smaller expected noise
// sigma_z(z, theta) in its own sensor: nearer and more head-on) stays and the other goes, so
// no doubled, differently coloured shell remains.
// Sources: docs/algorithms.md §6; CIE 1976 L*a*b* (sRGB D65); noise models of
// algorithms/denoise/sensor_noise.hpp. See also: algorithms/sampling/merge_views.hpp (plain
// concatenation), icp.hpp (align_views / apply_alignment give the poses).
#pragma once

#include <cstddef>
#include <vector>

#include "algorithms/denoise/sensor_noise.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"

namespace rgbd::registration {

struct DuplicateOptions {
    double radius_spacing = 1.0;  ///< r_dup as a multiple of ŝ
    double max_delta_e = 15.0;    ///< colours within this Delta E76 are the same
    /// ŝ in metres; 0 = the median of the views' robust spacings.
    double spacing_m = 0.0;
    /// Ranks observations (only the order matters).
    denoise::NoiseModel noise_model = denoise::NoiseModel::kKinectV2;
    void check() const;
};

struct DuplicateReport {
    std::size_t input = 0;       ///< points in
    std::size_t duplicates = 0;  ///< dropped: same colour as an earlier point within r_dup
    std::size_t replaced = 0;    ///< colours disagreed: the worse observed of the two dropped
    std::size_t output = 0;
    double radius_m = 0.0;
    Report to_json() const;
};

/// CIE 1976 colour difference of two sRGB colours (D65).
double delta_e76(Rgb a, Rgb b);

/// Merges views that are already in the world frame (apply_alignment) into one cloud without
/// duplicates. Views without colours merge as if all colours agreed; views without a pose or
/// normals rank observations by distance to the origin only. Deterministic for any thread
/// count. Throws InputError for a view in its sensor frame, non-finite points, bad options.
PointCloud merge_without_duplicates(std::vector<PointCloud>&& views,
                                    const DuplicateOptions& options,
                                    DuplicateReport* report = nullptr,
                                    const Progress& progress = {});

}  // namespace rgbd::registration
