// ChArUco calibration boards: the board description (squares, marker size, dictionary), its
// printable image, detection of its inner chessboard corners in a colour image with the pose of
// the board in the camera, and the check of that pose against a depth image (distance of the
// measured depth on the board to the board plane). Detection follows OpenCV's ChArUco module
// (Garrido-Jurado et al., "Automatic generation and detection of highly reliable fiducial
// markers under occlusion", Pattern Recognition 2014; OpenCV 4.6 aruco: detectMarkers,
// interpolateCornersCharuco, estimatePoseCharucoBoard). docs/algorithms.md §6.
// See also: rig_solver.hpp (joint solve of all extrinsics), cli/rgbd_calibrate.cpp.
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "toolkit/camera.hpp"
#include "toolkit/pose.hpp"

namespace rgbd::calibration {

/// A ChArUco board. Board frame: origin at the outer corner of the top-left square of the
/// printed image, x along the columns (to the right), y along the rows (down), z into the
/// board (x cross y), metres. Inner corner k (OpenCV's id) sits at
/// ((k % (squares_x - 1) + 1) square_m, (k / (squares_x - 1) + 1) square_m, 0).
struct BoardSpec {
    int squares_x = 7;                        ///< squares along x (columns)
    int squares_y = 5;                        ///< squares along y (rows)
    double square_m = 0.08;                   ///< edge of a chessboard square, metres
    double marker_m = 0.06;                   ///< edge of an ArUco marker, metres
    std::string dictionary = "DICT_5X5_100";  ///< OpenCV predefined dictionary name

    /// Throws InputError on sizes out of range (2..40 squares, marker smaller than the square,
    /// square 5 mm..2 m), an unknown dictionary or one with fewer markers than the board needs.
    void check() const;
    /// {"squares_x", "squares_y", "square_m", "marker_m", "dictionary"}.
    nlohmann::json to_json() const;
    /// From the JSON above (missing keys keep the defaults; unknown keys are errors). Throws
    /// InputError naming the key (the caller adds the file name).
    static BoardSpec from_json(const nlohmann::json& json);

    double width_m() const { return squares_x * square_m; }
    double height_m() const { return squares_y * square_m; }
    int corner_count() const { return (squares_x - 1) * (squares_y - 1); }
    /// Board-frame position of inner corner `id` (metres, z = 0).
    Eigen::Vector3d corner(int id) const;
};

/// The printable image of the board: CV_8UC1, white background, `pixels_per_m` pixels per
/// metre, no margin. Pixel (c, r) covers board points [c, c + 1) x [r, r + 1) / pixels_per_m:
/// board point (x, y) is at pixel coordinate (x, y) * pixels_per_m - 0.5 (pixel centres at
/// integers). Throws InputError for a bad spec, an image over 20000 pixels a side, or markers
/// too small to draw at this resolution (under the dictionary's bits + 4 pixels a side);
/// AlgorithmError if OpenCV fails anyway.
cv::Mat board_image(const BoardSpec& board, double pixels_per_m);

/// Options of detect_board.
struct DetectionOptions {
    int min_corners = 6;       ///< fewer interpolated corners: not a detection
    double max_rms_px = 2.0;   ///< reprojection RMS above this: rejected (wrong board, blur)
    double min_spread = 0.15;  ///< the corners must span this share of the board's diagonal
    /// Throws InputError on out-of-range values.
    void check() const;
};

/// The board seen in one colour image.
struct BoardObservation {
    std::vector<int> ids;                       ///< inner corner ids (BoardSpec::corner)
    std::vector<Eigen::Vector2d> pixels;        ///< their sub-pixel positions, colour image
    Pose camera_from_board = Pose::Identity();  ///< PnP estimate (colour camera frame)
    double rms_px = 0.0;                        ///< reprojection RMS of the corners at that pose
    int markers = 0;                            ///< ArUco markers found
};

/// Why an image gave no observation (for messages); empty when it did.
struct DetectionOutcome {
    std::optional<BoardObservation> observation;
    int markers = 0;       ///< markers of the board's dictionary found (0: no board visible)
    int corners = 0;       ///< corners interpolated
    std::string rejected;  ///< reason when markers were found but no observation was kept
};

/// Detects the board in `image` (CV_8UC3 BGR or CV_8UC1) seen by a camera with `intrinsics`
/// (distortion coefficients are used when present): ArUco markers, then the inner corners
/// interpolated from them with sub-pixel refinement, then the board pose by PnP on the
/// corners (iterative Levenberg-Marquardt). Throws InputError for a bad spec or image,
/// AlgorithmError naming the board and image size when OpenCV fails. Thread-safe.
DetectionOutcome detect_board(const cv::Mat& image, const PinholeIntrinsics& intrinsics,
                              const BoardSpec& board, const DetectionOptions& options = {});

/// Depth on the board: signed distances to the board plane placed at `depth_from_board` of the
/// depth pixels whose ray meets that plane inside the board (its outline shrunk by half a
/// square).
struct PlaneCheck {
    int pixels = 0;          ///< valid depth pixels inside the board
    double median_mm = 0.0;  ///< median signed distance (positive: depth behind the plane)
    double rms_mm = 0.0;     ///< RMS distance to the plane after removing the median
    bool valid() const { return pixels > 0; }
};

/// Compares the depth image (CV_32FC1 metres, NaN = invalid) of a camera with `intrinsics`
/// to the board plane at `depth_from_board` (board frame -> depth camera frame).
/// Distances are measured along the plane normal; pixels farther than `gate_m` from the plane
/// (a hand in front, flying pixels) are left out: the gate is wide by default so that a board
/// pose at the wrong scale (a board file that does not match the print) shows. Thread-safe.
PlaneCheck check_board_plane(const cv::Mat& depth_m, const PinholeIntrinsics& intrinsics,
                             const BoardSpec& board, const Pose& depth_from_board,
                             double gate_m = 1.0);

}  // namespace rgbd::calibration
