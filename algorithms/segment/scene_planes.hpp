// Steps 1 and 1b of the object extraction (algorithms/segment/subject_extraction.hpp): the ground
// and the walls, found over the pooled views, refitted and cut in each view. Internal to
// algorithms/segment; the planes' own fits are in ground_plane.hpp.
#pragma once

#include <cstddef>
#include <vector>

#include "algorithms/denoise/sensor_noise.hpp"
#include "algorithms/segment/subject_extraction.hpp"
#include "algorithms/segment/view_points.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/report.hpp"

namespace rgbd::segment::detail {

/// Step 1: finds the ground in the views (detail::pooled_ground), refits it per view
/// (detail::refit_view_ground) and, when the views see it flat and as the lowest large surface,
/// cuts above each view's plane (detail::cut_above_ground), writes that plane into the view's
/// metadata and marks the cut points removed. Returns the report's "ground" section.
Report remove_ground(std::vector<ViewPoints>& vps, std::vector<PointCloud>& views,
                     const std::vector<denoise::NoiseModel>& noise, const SubjectOptions& options,
                     std::size_t total);

/// Step 1b: the walls, the large planes that bound what the sensors see (docs/algorithms.md
/// §3): among the points left after the ground, up to 6 planes of any orientation
/// (detail::pooled_bounding_plane), each a wall when at most wall_max_behind_share of the
/// points lie more than a band behind it, every sensor lies in front of it (it bounds the space
/// the sensors are in: a face of a subject seen from around has sensors behind it), and half
/// the views see it flat in units of their sensor's noise (detail::refit_view_ground, the
/// ground's test);
/// each view then cuts it with the ground's noise margin (detail::cut_above_ground). An object's
/// face has the rest of the scene behind its plane; a wall has (almost) nothing. The flatness
/// bound is ground_flat_sigmas times `ground_flatness` (the ground's own median flatness, in
/// sigma_z, when it was found and is above 1; else 1): the ground shows how much noisier the
/// real sensor is than its model, and a wall of the same scene, seen by the same sensors, is
/// judged in that noise. And in the median of the views that see it, at most
/// wall_max_through_share of a view's points are seen through the view's own refit of the plane
/// (more than half a band behind it, their line of sight crossing it inside the convex hull of
/// its facing points: a wall hides what is behind it). The candidates refused as not flat or
/// seen through may be slices through a wall and what leans on it: after the six rounds, their
/// samples are searched again in four rounds with a wall_split_tilt_deg voting cone, each
/// candidate judged alike (report `second_pass`).
Report remove_walls(std::vector<ViewPoints>& vps, const std::vector<PointCloud>& views,
                    const std::vector<denoise::NoiseModel>& noise, const SubjectOptions& o,
                    double ground_flatness);

}  // namespace rgbd::segment::detail
