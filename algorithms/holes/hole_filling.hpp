// Small-hole filling on point sets (docs/algorithms.md §11): the four mechanisms named by the
// thesis, in our reconstruction [R]: M1 one point on the bisector of a rim point's largest angular
// gap, M2 one point on each of its four largest gaps, M3 three points splitting its largest gap,
// all three swept over the rim until the hole closes; M4 interpolation of the whole hole at once
// (quadric fitted to the hole's surroundings, hexagonal grid at the point spacing inside the
// rim). Every new point is projected on a local quadric fitted to *original* points only (so
// sweeps do not accumulate noise), is rejected when it duplicates a point or lies outside the
// rim (no outward growth), and gets an interpolated colour.
// Peers: CGAL Polygon_mesh_processing::triangulate_refine_and_fair_hole on a mesh of the cloud,
// PCL MovingLeastSquares VOXEL_GRID_DILATION (validation/quality/holes/).
// See also: algorithms/holes/hole_detection.hpp (§10 gives the loops filled here).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "algorithms/holes/hole_detection.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"

namespace rgbd::holes {

enum class FillMechanism : std::uint8_t {
    kOnePoint = 1,       ///< M1: one point at the largest angle (gap > 90 degrees)
    kFourPoints = 2,     ///< M2: one point at each of the four largest angles (> 60 degrees)
    kThreePoints = 3,    ///< M3: three points splitting the largest angle (> 120 degrees)
    kInterpolation = 4,  ///< M4: whole-hole quadric + hexagonal grid
    kLargeHole = 5,      ///< §12: cylindrical unwrapping + Telea (large_holes.hpp)
    kHeadTop = 6,        ///< §13: top-down height map + ellipsoid / Telea (large_holes.hpp)
};
/// "one", "four", "three", "interpolation", "large-hole", "head-top".
const char* to_string(FillMechanism mechanism);
/// Parses the small-hole names above (also "m1".."m4"); throws InputError.
FillMechanism parse_fill_mechanism(const std::string& name);

struct FillOptions {
    /// Mechanism used on every small loop. Default: the best measured on the synthetic holes of
    /// tests/algorithms/holes/hole_filling_test.cpp and the bust of
    /// validation/quality/holes/measure_fill.py (distance to the true surface, closure).
    FillMechanism mechanism = FillMechanism::kInterpolation;
    double step = 1.0;                ///< insertion distance h, in spacings (M1-M3)
    int quadric_k = 20;               ///< original points of the local quadric fit
    int color_k = 6;                  ///< original points of the IDW colour (M2, M4)
    double duplicate_distance = 0.5;  ///< reject a new point this close to another (spacings)
    int max_sweeps = 20;              ///< M1-M3: sweeps over the rim at most
    /// M4: a grid point is kept only when no measured point lies within this many spacings.
    /// Below ~0.9 the grid also densifies the rim band, whose sample gaps exceed 0.7 spacings
    /// (measure_fill.py: 86 points outside the cut balls at 0.7, see the commit).
    double grid_clearance = 0.9;
    /// M4: the hole is filled only when the quadric fits the original points around it within
    /// this many spacings (weighted RMS); a larger residual means the surroundings are no
    /// smooth sheet (a crease behind an ear, two layers meeting) and the quadric would bridge
    /// the hole above the true surface (measure_ring.py, Max Planck: such loops put 11-30 % of
    /// their points farther than 5 mm from the truth).
    double max_fit_rms = 2.0;
    /// M4: every grid point lifted on the hole's quadric is projected again on the quadric of
    /// its quadric_k nearest original points (the MLS projection of M1-M3, without their move
    /// limit): the measured points next to a new point decide where the surface is, the hole's
    /// single quadric only where the point goes. Off: the hole's quadric alone (the earlier
    /// behaviour; it rounds off creases, ablation.py's bear: 2.3% of the points > 5 mm).
    bool local_projection = true;
    bool fill_openings = false;  ///< also fill loops the sensors saw through
    /// Inside test: a candidate is inside the hole when the directions to the rim points leave
    /// no angular gap wider than this (degrees); outside a closed rim the gap exceeds 180.
    double inside_max_gap_deg = 170.0;
    void check() const;
};

/// Points added by the filling, in the frame of the SurfacePoints.
struct FillResult {
    std::vector<Eigen::Vector3d> position;
    std::vector<Eigen::Vector3d> normal;
    std::vector<Rgb> color;                ///< interpolated (grey when the input has no colour)
    std::vector<FillMechanism> mechanism;  ///< mechanism that added each point
    std::vector<std::uint32_t> loop;       ///< index into BoundaryResult::loops
    std::size_t loops_filled = 0;          ///< loops that got at least one point
    int sweeps = 0;                        ///< sweeps run (M1-M3)
};

/// Fills the small loops of `detection` (kind occlusion or unknown; openings only with
/// fill_openings) of `points` with `options.mechanism`. `detection` must come from
/// detect_boundaries on the same points. TBB-parallel where it matters, deterministic.
/// Report: mechanism, loops considered / filled, points added, sweeps, loops skipped for a
/// poor quadric fit (M4), time_s.
FillResult fill_small_holes(const SurfacePoints& points, const BoundaryResult& detection,
                            const FillOptions& options, Report* report = nullptr,
                            const Progress& progress = {});

}  // namespace rgbd::holes
