// Rigid poses. Named target_from_source (docs/architecture.md, the data model): p_in_world =
// world_from_sensor * p_in_sensor.
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <optional>
#include <vector>

namespace rgbd {

using Pose = Eigen::Isometry3d;

/// Angle of the rotation between two poses, in degrees: acos((trace(R_a R_b^T) - 1) / 2).
double rotation_error_deg(const Pose& a, const Pose& b);
/// Distance between the translations of two poses, in metres.
double translation_error_m(const Pose& a, const Pose& b);
/// Builds a pose from 12 numbers (3x4, row-major). Throws InputError if the rotation part
/// is not a rotation (orthonormal within 1e-4, det +1) or a value is not finite.
Pose pose_from_3x4(const std::array<double, 12>& rows);
/// Same from 16 numbers (4x4 row-major); the last row must be 0 0 0 1.
Pose pose_from_4x4(const std::array<double, 16>& rows);
/// The 12 numbers of the 3x4 row-major form.
std::array<double, 12> pose_to_3x4(const Pose& pose);
/// The world's "up" as a set of sensors sees it: the normalised mean of their image-up axes
/// (minus each camera's y axis: image rows grow downwards). nullopt when there are no sensors
/// or their up axes disagree, i.e. the mean is shorter than `min_agreement` (1 = all equal;
/// a level ring of sensors gives about cos(tilt)).
std::optional<Eigen::Vector3d> sensors_up(const std::vector<Pose>& world_from_sensor,
                                          double min_agreement = 1e-6);
/// Re-orthonormalises the rotation part (nearest rotation, by SVD).
Pose orthonormalized(const Pose& pose);
/// Camera pose at `position` looking at `target` (OpenCV frame: x right = z x up, y down,
/// z forward), with `up` the world up direction. Throws InputError when the two points
/// coincide or the view direction is parallel to `up`.
Pose look_at(const Eigen::Vector3d& position, const Eigen::Vector3d& target,
             const Eigen::Vector3d& up = Eigen::Vector3d::UnitZ());

}  // namespace rgbd
