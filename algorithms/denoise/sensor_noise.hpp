// Depth sensor noise models shared by the adaptive filters (docs/algorithms.md §4 (noise models),
// §4, §8): axial noise sigma_z(z, theta), the per-pixel footprint s_d(z) = z / f and the largest
// depth step a real surface can make between neighbouring pixels, dz_max(z) = s_d(z) tan(theta_max)
// + 3 sigma_z(z). Sources: Fankhauser et al., ICAR 2015 (Kinect v2, constants recalled, see §2.3);
// Nguyen, Izadi, Lovell 2012 (Kinect v1); SR300 model of validation/synth/noise.hpp.
// See also: distance_outliers.hpp, density_outliers.hpp.
#pragma once

#include <string>

namespace rgbd::denoise {

/// Axial depth noise model of the sensor that produced a view.
enum class NoiseModel {
    kKinectV2,  ///< sigma_z [mm] = 1.5 - 0.5 z + 0.3 z^2 + 0.1 z^1.5 theta^2 / (pi/2 - theta)^2
    kKinectV1,  ///< sigma_z [m] = 0.0012 + 0.0019 (z - 0.4)^2
    kSr300,     ///< sigma_z [mm] = 0.5 + 2 z^2 + 0.1 z^1.5 theta^2 / (pi/2 - theta)^2
    kGeneric,   ///< sigma_z [m] = 0.0015 (z / 1.5)^2 (§2.3 default when no model is known)
};

/// "kinect_v2", "kinect_v1", "sr300" or "generic".
std::string to_string(NoiseModel model);
/// Parses the names of to_string(); throws InputError for anything else.
NoiseModel parse_noise_model(const std::string& name);

/// Axial noise standard deviation in metres at depth z_m and incidence theta_rad (clamped to
/// [0, 89 degrees]; 0 = head-on).
double sigma_z_m(NoiseModel model, double z_m, double theta_rad = 0.0);

/// Largest depth difference between two 8-neighbouring pixels on a real surface at depth z_m:
/// (z / focal_px) tan(theta_max) + 3 sigma_z(z).
double max_depth_step_m(NoiseModel model, double z_m, double focal_px, double theta_max_rad);

}  // namespace rgbd::denoise
