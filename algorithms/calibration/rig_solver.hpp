// Joint calibration of a sensor network from board observations: every sensor that sees the
// board in the same frame set as another is linked to it; a spanning tree from the anchor gives
// the start, and a bundle adjustment over all observations (unknowns: every colour camera's pose
// but the anchor's, and the board's pose in every frame set seen by two or more sensors;
// residuals: corner reprojection errors in pixels, Huber-weighted) solves all extrinsics at once,
// so that no error piles up around the ring. Levenberg-Marquardt on SE(3) with left
// perturbations (Triggs et al., "Bundle adjustment - a modern synthesis", 1999, §4, §6;
// the graph view as in Kümmerle et al., g2o, ICRA 2011). docs/algorithms.md §6.
// See also: charuco_board.hpp (observations), cli/rgbd_calibrate.cpp.
#pragma once

#include <string>
#include <vector>

#include "algorithms/calibration/charuco_board.hpp"
#include "toolkit/camera.hpp"
#include "toolkit/pose.hpp"

namespace rgbd::calibration {

/// One sensor's view of the board in one frame set.
struct Observation {
    int sensor = 0;    ///< index into the camera list
    int frameset = 0;  ///< frame-set number: observations with the same number are simultaneous
    BoardObservation board;
};

/// Options of solve_rig.
struct RigSolveOptions {
    int anchor = 0;            ///< camera whose pose is fixed (the gauge)
    int max_iterations = 100;  ///< Levenberg-Marquardt iterations
    double huber_px = 1.5;     ///< Huber kernel scale, pixels
    /// Throws InputError on out-of-range values.
    void check() const;
};

/// Per-camera result.
struct CameraSolution {
    Pose anchor_from_camera = Pose::Identity();  ///< colour camera in the anchor's colour frame
    int observations = 0;                        ///< frame sets in which the camera saw the board
    int linked = 0;       ///< of which shared with another connected camera (used in the solve)
    double rms_px = 0.0;  ///< reprojection RMS of its corners in the solve (0 when none)
    bool connected = false;
};

struct RigSolution {
    std::vector<CameraSolution> cameras;  ///< same order as the input
    std::vector<int> unconnected;         ///< cameras not linked to the anchor by co-observations
    int boards = 0;                       ///< board poses solved (frame sets seen by 2+ cameras)
    int residuals = 0;                    ///< corners in the solve
    double initial_rms_px = 0.0;          ///< reprojection RMS at the spanning-tree start
    double final_rms_px = 0.0;            ///< after the bundle adjustment
    int iterations = 0;
};

/// Cameras (indices) that no chain of co-observations links to `anchor`. Sorted.
std::vector<int> unconnected_cameras(int cameras, const std::vector<Observation>& observations,
                                     int anchor);

/// Solves the colour cameras' poses relative to the anchor from all observations.
/// `intrinsics`: the colour camera of every sensor (distortion applied in the projection).
/// Cameras that are not connected keep the identity and are listed in `unconnected` (the solve
/// runs on the connected ones). Throws InputError for an anchor out of range or an observation
/// naming a camera out of range; AlgorithmError when the anchor has no linked observation.
RigSolution solve_rig(const std::vector<PinholeIntrinsics>& intrinsics,
                      const std::vector<Observation>& observations, const BoardSpec& board,
                      const RigSolveOptions& options = {});

}  // namespace rgbd::calibration
