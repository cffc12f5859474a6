// depth_to_cloud: one RGB-D frame -> one organised, coloured point cloud in the sensor frame,
// with object extraction by depth window and mask.
//
// Implements docs/algorithms.md §2 (back-projection with distortion, depth -> colour mapping,
// z-buffer visibility test, bilinear colour sample) and §3 step 1 (depth window) plus the
// frame's object mask. The visibility test follows libfreenect2 `Registration::apply` (filter
// option): a depth point hidden from the colour camera gets no colour from the colour image.
// See also: toolkit/camera.hpp (PinholeIntrinsics::project/unproject), toolkit/rgbd_frame.hpp,
// Open3D `PointCloud::CreateFromRGBDImage` (the peer; it needs registered, same-size images).
#pragma once

#include "toolkit/point_cloud.hpp"
#include "toolkit/report.hpp"
#include "toolkit/rgbd_frame.hpp"

namespace rgbd::frames {

/// uint8 flag property: 1 = the colour image did not see this point (hidden behind a nearer
/// surface for the colour camera, or outside the colour image); its colour was copied from the
/// nearest coloured point of the same view (3D distance), or grey when there is none.
inline constexpr const char* kUncoloured = "uncoloured";

/// Options of depth_to_cloud().
struct CloudOptions {
    /// Depth window [z_min_m, z_max_m] in metres (§3 step 1). 0 = use the frame's
    /// range_min_m / range_max_m when set, else no bound.
    double z_min_m = 0.0;
    double z_max_m = 0.0;
    /// Keep only pixels where the frame's mask (if present) is nonzero.
    bool use_mask = true;
    /// Run the z-buffer visibility test of §2 step 3. Off: every point inside the colour
    /// image takes the colour it projects to (Kinect SDK behaviour, colour bleeds).
    bool visibility_test = true;
    /// Visibility tolerance: a point is hidden when its colour-camera depth exceeds the
    /// z-buffer by more than sigma_factor * sigma_z(z) + occlusion_margin_m, with the default
    /// noise model of §2.3, sigma_z(z) = 0.0015 (z / 1.5)^2 m.
    double sigma_factor = 2.0;
    double occlusion_margin_m = 0.005;
    /// Size of a z-buffer splat relative to the footprint of one depth pixel in the colour
    /// image (> 1 closes the cracks between neighbouring splats on slanted surfaces).
    double splat_scale = 1.25;
    /// Upper bound of the splat half-width in colour pixels (guards against absurd ratios).
    int max_splat_radius_px = 8;
    /// Colour given to uncoloured points when no coloured point exists in the view.
    Rgb fallback_color{128, 128, 128};
    /// Colour the points the colour camera does not see from the nearest point it does see
    /// (3D distance, over the whole view). false: they keep fallback_color, flagged kUncoloured,
    /// for colour_uncoloured() to colour once the view is cut to the subject (a Kinect v2 view
    /// has ~100,000 points of which ~15,000 are the subject's: the search over the whole view's
    /// coloured points was most of the cloud stage's time).
    bool colour_hidden = true;

    /// Throws InputError on absurd values (negative or inverted window, non-positive scale...).
    void check() const;
};

/// Back-projects every valid depth pixel of `frame` into a point of the depth camera frame.
///
/// A pixel is kept when its depth is finite and > 0, inside the depth window and (with
/// use_mask) nonzero in the frame's mask. Points are stored in row-major pixel order.
/// Properties: `pixel` (row * width + col), `red green blue` (sRGB, from the BGR colour image;
/// only when the frame has a colour image), kUncoloured flag (same condition), `confidence`
/// (the frame's confidence image when present, else 1.0). ViewInfo: frame = kSensor, grid =
/// depth size, intrinsics = depth intrinsics, world_from_sensor = frame pose when has_pose,
/// sensor, time_ns, source.
///
/// @param frame    depth CV_32FC1 (metres, NaN/0 invalid), optional colour CV_8UC3 BGR of the
///                 colour intrinsics' size, optional mask CV_8UC1 and confidence CV_32FC1 of
///                 the depth size.
/// @param options  see CloudOptions; checked first.
/// @param report   when not null, receives resolved window, counts (valid, removed by
///                 window/mask, invalid, uncoloured hidden/outside) and time_s.
/// @throws InputError naming the frame for inconsistent sizes/types or invalid intrinsics.
PointCloud depth_to_cloud(const RgbdFrame& frame, const CloudOptions& options,
                          Report* report = nullptr);

/// The colouring of depth_to_cloud's hidden and outside points on its own: every point of
/// `cloud` flagged kUncoloured takes the colour of the nearest point that is not (3D distance,
/// in the cloud's frame), or `fallback` when no point is coloured; the flag stays. Returns how
/// many points it coloured. A cloud without colours or the flag is left as it is.
std::size_t colour_uncoloured(PointCloud& cloud, const Rgb& fallback);

}  // namespace rgbd::frames
