// Large holes and the head top (docs/algorithms.md §12 and §13): 3D inpainting built on 2D
// inpainting. The surface is turned into images where inpainting is meaningful, the images are
// inpainted by Telea's fast-marching method (OpenCV cv::inpaint, INPAINT_TELEA, on a float
// image for the geometry), and the inpainted pixels are turned back into points.
// - §12, large holes: cylindrical unwrapping around the body's vertical axis (radius and colour
//   images over angle x height), hole = unknown pixels between the lowest and the highest
//   known pixel of their column (the bust's bottom cut and the open top stay outside), Telea
//   then a biharmonic solve [M] on the radius, a 3x3 median, back-projection of the hole
//   pixels only, at the point spacing. Holes a sensor looked through (§10's visibility test)
//   stay open. Holes whose rim does not face away from the axis (chin overhang, arms: the
//   surface is not star-shaped there) are left alone.
// - §13, head top: the crown that a level ring of sensors never sees. Top-down height map of the
//   top of the body; hole = unknown pixels inside the convex hull of the known ones; height =
//   an ellipsoid fitted to the top points plus the rim's residual (measured - ellipsoid, 5 x 5
//   median) carried into the hole by a harmonic solve [M], so the crown has the ellipsoid's
//   shape and meets the rim without a step; a top that is no ellipsoid stays open by default.
//   Normals from the height-map gradient.
// Colour (§12.2): Criminisi's exemplar-based inpainting (exemplar_inpaint.hpp) on the hole
// pixels of both images, by default; Telea as an option (and where no exemplar fits).
// The vertical axis comes from the sensor poses (normal of the plane through the sensor
// centres: the ring is level), else from the cloud's principal axis.
// Peers: Open3D Screened Poisson closes every hole; CGAL triangulate_refine_and_fair_hole on a
// mesh of the cloud (rgbd-mesh --watertight); validation/quality/holes/measure_ring.py.
// See also: algorithms/holes/hole_filling.hpp (§11, the small holes).
#pragma once

#include <Eigen/Core>
#include <limits>
#include <vector>

#include "algorithms/holes/free_space.hpp"
#include "algorithms/holes/hole_detection.hpp"
#include "algorithms/holes/hole_filling.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"

namespace rgbd::holes {

/// The body's vertical axis: a point on it and the unit up direction.
struct BodyAxis {
    Eigen::Vector3d origin = Eigen::Vector3d::Zero();
    Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
    bool from_sensors = false;  ///< from the sensor ring, else from the principal axis
};

/// §12.1 step 1. With three or more sensor centres that span a plane: the plane's normal,
/// pointing to where the cameras' "up" (-y of the image) points on average. Else the major
/// principal axis of the points, pointing to the side whose end is narrower (a bust's head).
/// The origin is the centroid of the points. InputError for an empty set.
BodyAxis estimate_body_axis(const SurfacePoints& points, const std::vector<SensorView>& sensors);

/// §12.2: how the colour of the hole pixels is inpainted.
enum class ColourInpaint {
    kCriminisi,  ///< exemplar-based (texture stays texture); Telea where no exemplar fits
    kTelea,      ///< fast marching (smooth; blurs texture)
};

struct InpaintOptions {
    double pixel = 1.5;         ///< image pixel size, in spacings (§12.1 step 3)
    double telea_radius = 5.0;  ///< Telea's neighbourhood radius, pixels (§12.2)
    ColourInpaint colour = ColourInpaint::kCriminisi;  ///< §12.2
    int patch = 9;                                     ///< Criminisi's patch side, pixels (odd)
    double search_window = 4.0;  ///< Criminisi's search window, multiple of the hole's box
    double wrap = 0.1;           ///< cylinder padding each side, fraction of the width
    int min_component = 4;       ///< smaller hole components are left to §11 (pixels)
    double step = 1.0;           ///< spacing of the new points, in spacings
    /// No new point within this many spacings of an existing one (the rim band is not
    /// densified).
    double clearance = 0.9;
    bool median = true;  ///< 3x3 median on the inpainted radius (§12.3)
    /// Geometry [M]: solve the biharmonic equation for the radius / height inside the hole
    /// (continues the rim's slope and curvature; OpenCV's Telea flattens), Telea's result
    /// where the solve fails.
    bool biharmonic = true;
    /// ... except in large holes whose radius changes faster than their height (mean |dr/dh|
    /// of Telea's radius over the hole above this): the underside of an overhang, closer to
    /// horizontal than vertical, whose rims are creases: there the harmonic solve (the rims'
    /// values, not their slopes; §12.2 [M]).
    double max_biharmonic_slope = 1.0;
    /// Star-shape test [M]: a hole is filled only when the mean of n . radial over its rim
    /// pixels is at least this (0.45: rim normals within ~63 degrees of horizontal-outward).
    double min_rim_radial = 0.45;
    /// Enclosure test [M]: a hole is filled only when at most this share of its edge (pixel
    /// sides) borders the outside of the surface (below the lowest or above the highest known
    /// pixel of a column) rather than measured pixels: a notch in the open bottom boundary is
    /// no hole, and the surface beyond the lowest observed ring is not predicted by a rim
    /// (left to the mesher). 1 = no test.
    double max_open_rim = 1.0;
    /// Step test [M]: the largest RMS mismatch, in spacings, between the two sides of a hole
    /// (the radius below and above it, each continued across by its own slope) for the hole to
    /// be filled; infinity = no test (see fill_large_holes).
    double max_step_rms = 3.0;
    double top_fraction = 0.12;  ///< §13 step 1: the top region's share of the height
    /// §13 step 2 [M]: a column of the top-down height map is known only when its highest point's
    /// outward normal has at least this component along the up axis. A ring below the crown sees
    /// the chin and the jaw from below: they face down, so the body lies above them and the
    /// column's top was not seen (taken as known, such columns pulled the inpainted crown 5-55 mm
    /// low on a standing man whose head is above the sensors). The bound sits a little below 0 (5.7
    /// degrees): a wall seen edge-on tops its columns with normals that scatter around horizontal,
    /// and with 0 many of them made thin strips of unseen tops between seen pixels, into which the
    /// crown was carried (the standing man, seed 2: 2.5% of the crown's points 5-12 mm off); the
    /// chin and the jaw face down by more (-0.4, 24 degrees, took some of them as seen again). -1 =
    /// every column with a point (the dissertation's map).
    double top_min_up = -0.1;
    /// §13 [M]: head-top hole components smaller than this share of the largest one are
    /// sampling gaps among seen pixels, not the crown (left to §11).
    double top_component = 0.1;
    bool ellipsoid = true;  ///< §13 step 4: ellipsoid height (else inpainted only)
    /// §13 step 4 [M]: the ellipsoid is fitted to the top points at most this many hole radii
    /// (the equivalent radius of the hole's area) below the highest one: the crown's
    /// neighbourhood. The top region is a share of the whole height, which on a standing figure
    /// reaches the neck and the chin: an ellipsoid through them is taller and more pointed than
    /// the crown, and put a standing man's crown up to 14 mm too high (58% of its points farther
    /// than 5 mm; 2: none). 0 = every top point (the dissertation's fit).
    double top_fit_radii = 2.0;
    /// ... used only when the fit's RMS residual over the top points is at most this many
    /// spacings (a wreath or a hat is no ellipsoid).
    double max_ellipsoid_rms = 3.0;
    /// When the ellipsoid does not fit: fill with the inpainted heights (true) or leave the
    /// crown open (false, default: measured on the wreathed bust, the inpainted crown put 20 %
    /// of its points farther than 5 mm from the truth; validation/quality/holes/measure_ring.py).
    bool top_without_ellipsoid = false;
    /// Visibility (as §10): a hole some sensor faced within this angle with a clear line of
    /// sight is a real opening (a sensor looked through it and measured nothing): left open
    /// unless fill_openings. No sensors: every hole is filled.
    double visible_max_angle_deg = 60.0;
    double ray_clearance = 1.0;
    bool fill_openings = false;
    /// [M] (§12.3 / §13 step 5, proposed §12.4): a proposed point that a sensor saw as empty
    /// space (a clear, front-facing line of sight and the measured surface well behind it, or
    /// background; free_space.hpp) is invented: dropped. Needs sensors; off with
    /// fill_openings (the same evidence).
    bool carve = true;
    FreeSpaceOptions free_space;
    /// [M] (§12.3 / §13 step 5, proposed §12.4): a hole component whose proposed points the sensors
    /// contradict in more than this share is dropped whole: its inpainting disagrees with what was
    /// measured, and its unseen part is no more trustworthy than its seen part (a bulge is carved
    /// where a sensor saw past it and survives where none could). Measured on the 16 objects of
    /// the variety set (validation/results/2026-11-27-variety-after-*.md): every fill that
    /// matches the truth is contradicted in at most 0.05% of its points (crowns of Max Planck,
    /// the mannequin, Homer, a standing man; large holes of nine objects), the lid the head top
    /// proposed over an open jug's mouth in 15.5% (kept at 0.2: 8488 points, 95% of them farther
    /// than 5 mm from the truth, up to 106 mm).
    double max_contradicted = 0.05;
    void check() const;
};

/// §13: fills the top of the body. `normals` are the points' unit normals (outward). The added
/// points carry mechanism kHeadTop and loop = 0. Report: top region points, hole pixels,
/// ellipsoid semi-axes, points added, time_s.
FillResult fill_head_top(const SurfacePoints& points, const std::vector<Eigen::Vector3d>& normals,
                         const BodyAxis& axis, double spacing_m,
                         const std::vector<SensorView>& sensors, const InpaintOptions& options,
                         Report* report = nullptr, const Progress& progress = {});

/// §12: fills large holes by cylindrical unwrapping. Pixels higher than `top_limit` (height
/// along the axis from its origin) are left alone (the head top's business). The added points
/// carry mechanism kLargeHole and loop = the hole component's index. Report: image size, hole
/// components filled / skipped (small, not star-shaped, seen through), hole pixels, points added,
/// time_s.
FillResult fill_large_holes(const SurfacePoints& points,
                            const std::vector<Eigen::Vector3d>& normals, const BodyAxis& axis,
                            double spacing_m, const std::vector<SensorView>& sensors,
                            const InpaintOptions& options,
                            double top_limit = std::numeric_limits<double>::infinity(),
                            Report* report = nullptr, const Progress& progress = {});

/// Height (along `axis`) above which fill_head_top works for these points.
double head_top_start(const SurfacePoints& points, const BodyAxis& axis,
                      const InpaintOptions& options);

}  // namespace rgbd::holes
