// Refining a sensor network's extrinsics on what the sensors see (rgbd-calibrate --refine,
// issue 19; docs/algorithms.md §6b): the depth of a still scene combined over several frame
// sets (per-pixel mean around the median), and the settings of the toolkit's multi-view
// registration (registration::align_views, docs/algorithms.md §6) for a rig that is roughly right.
// Why (measured on synthetic bust captures with truth, validation/quality/calibration): on a
// rounded object the surface hardly pins a sensor's rotation about the object's centre (0.2 deg
// moves a bust's surface by ~0.5 mm), so with one frame set the per-pixel depth noise (Kinect v2
// ~1.4 mm at 1.5 m, more at grazing incidence) leaves ~0.3 deg: started at the true poses the
// registration also ends ~0.3 deg off. 8 frame sets cut that noise by ~2.8x when their agreeing
// depths are averaged; their median (the earlier combination) cut it by ~2.3x only and was
// biased by ~+0.05 mm on the 1 mm steps of the sensors' depth images: with geometry alone
// (no colour term) a ring of 4 around a held-out bust then ended 0.36 deg off instead of 0.08
// (issue 39, validation/results/2026-11-27-calibration-refine-*.md). See also:
// cli/rgbd_calibrate.cpp.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "algorithms/registration/icp.hpp"

namespace rgbd::calibration {

/// Per-pixel combination of depth images of a still scene from one sensor (CV_32FC1, metres, NaN
/// or <= 0 = invalid; all the same size): the mean of the valid depths within `agree_m` +
/// `agree_ratio` x depth of their median. A pixel is valid in the result when more than half of
/// the images have a valid depth there and more than half lie within that tolerance (so a pixel
/// that something moved through is left out rather than blurred). For Gaussian noise the mean of
/// n values has sigma / sqrt(n), the median ~1.2 sigma / sqrt(n) (n = 8), and the median of
/// depths quantised to 1 mm moves in 0.5 mm steps. One image is returned as it is. Throws
/// InputError on an empty list, sizes or types that differ, or a negative tolerance.
cv::Mat combined_depth(const std::vector<cv::Mat>& depths, double agree_m = 0.01,
                       double agree_ratio = 0.01);

/// align_views settings for refining a rig that is roughly right (a few degrees, a few cm):
/// - no pairwise stage: every view starts where the rig puts it and all are refined jointly
///   (each pinned by its neighbours on both sides). The pairwise stage slid or lost pairs on
///   rings of 4 and 6 sensors (neighbours 90 degrees apart are not paired at all; pair ICP from
///   ~100 mm off lost the overlap), and its pose graph then refused views the joint rounds had
///   placed well;
/// - distances 25, 12, 6, 3, 1.5, 1 x the point spacing: the first (~10 cm) covers where a
///   3 deg / 30 mm error puts the object 1.5 m away, the last (with the Tukey kernel at half
///   of it) keeps the grazing-incidence points, the noisiest, from pulling;
/// - working voxel 0.8 x the spacing and no cap on the working points (all measured points;
///   the rig's views are few);
/// - a view overlapping less than `warn_fitness` = 0.15 of its points is WARN (4 sensors 90
///   degrees apart share ~1/3 of their points), less than 0.1 FAIL; a view moved more than
///   20 degrees or 0.2 m is FAIL (a roughly right rig does not move that far).
/// `fixed_view`: the anchor's position in the view list; `seed`: the run's seed.
registration::MultiViewOptions rig_refinement_options(std::size_t fixed_view, std::uint64_t seed);

}  // namespace rgbd::calibration
