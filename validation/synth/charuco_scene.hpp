// Synthetic calibration captures (rgbd-synth --target charuco, issue 19): a rigid ChArUco board
// carried through the ring's volume in random poses, one pose per frame set, rendered by every
// sensor of the virtual ring (depth and colour with the usual noise; the board is printed on one
// side only, so in each frame set only the sensors in front of it see it), with the usual wrong
// rig.json. gt/world_from_depth.json has the true sensor poses, gt/board_poses.json the true
// world_from_board per frame set, gt/board.json the board. docs/algorithms.md, synthetic ground
// truth, and §6. See also: synthesize.hpp (the ring, the noise, the folder),
// algorithms/calibration/.
#pragma once

#include <filesystem>

#include "algorithms/calibration/charuco_board.hpp"
#include "toolkit/progress.hpp"
#include "validation/synth/synthesize.hpp"

namespace rgbd::synth {

/// How the board is carried through the ring.
struct BoardMotion {
    calibration::BoardSpec board;   ///< the printed board
    double margin_m = 0.02;         ///< white plate around the printed board
    double radius_m = 0.3;          ///< board centres uniform in this ball around the ring centre
    double facing_jitter_deg = 15;  ///< the board faces between two neighbouring sensors, off
                                    ///< by up to this much in azimuth and elevation
    double roll_deg = 30;           ///< in-plane rotation, uniform in [-roll, roll]
    double blur_px = 0;             ///< Gaussian blur of the colour images (sigma, pixels)
    double texture_mm = 0.25;       ///< texel of the printed image, millimetres

    /// Throws InputError on out-of-range values.
    void check() const;
    nlohmann::json to_json() const;
};

/// True world_from_board of frame set `set` (deterministic in options.seed); the ring centre
/// is `centre`, the sensors of the ring `sensor_positions`.
Pose board_pose(const BoardMotion& motion, const SynthOptions& options, int set,
                const Eigen::Vector3d& centre,
                const std::vector<Eigen::Vector3d>& sensor_positions);

/// Writes a ring capture of the moving board (options.rig must be the ring; options.frames
/// frame sets) to `out_dir`, atomically as synthesize_capture. Throws InputError / IoError.
SynthSummary synthesize_charuco_capture(const std::filesystem::path& out_dir,
                                        const SynthOptions& options, const BoardMotion& motion,
                                        const Progress& progress = {});

}  // namespace rgbd::synth
