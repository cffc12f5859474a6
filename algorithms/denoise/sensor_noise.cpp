#include "algorithms/denoise/sensor_noise.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "toolkit/enum_names.hpp"
#include "toolkit/error.hpp"

namespace rgbd::denoise {

namespace {
constexpr EnumName<NoiseModel> kNoiseModelNames[] = {{NoiseModel::kKinectV2, "kinect_v2"},
                                                     {NoiseModel::kKinectV1, "kinect_v1"},
                                                     {NoiseModel::kSr300, "sr300"},
                                                     {NoiseModel::kGeneric, "generic"}};
}  // namespace

std::string to_string(NoiseModel model) { return name_of(kNoiseModelNames, model, "generic"); }

NoiseModel parse_noise_model(const std::string& name) {
    if (const auto model = value_of(kNoiseModelNames, name)) return *model;
    throw InputError("unknown noise model '" + name +
                     "' (expected kinect_v2, kinect_v1, sr300 or generic)");
}

double sigma_z_m(NoiseModel model, double z, double theta) {
    constexpr double kHalfPi = std::numbers::pi / 2.0;
    const double t = std::clamp(theta, 0.0, 89.0 * std::numbers::pi / 180.0);
    // Head-on (t = 0, the hot case of the filters) the grazing term is 0: skip the pow.
    const double grazing =
        t == 0.0 ? 0.0
                 : 0.1 * std::pow(std::max(z, 0.0), 1.5) * t * t / ((kHalfPi - t) * (kHalfPi - t));
    switch (model) {
        case NoiseModel::kKinectV2:
            return 1e-3 * std::max(0.5, 1.5 - 0.5 * z + 0.3 * z * z + grazing);
        case NoiseModel::kKinectV1:
            return 0.0012 + 0.0019 * (z - 0.4) * (z - 0.4);
        case NoiseModel::kSr300:
            return 1e-3 * (0.5 + 2.0 * z * z + grazing);
        case NoiseModel::kGeneric:
            return 0.0015 * (z / 1.5) * (z / 1.5);
    }
    return 0.0015 * (z / 1.5) * (z / 1.5);
}

double max_depth_step_m(NoiseModel model, double z, double focal_px, double theta_max_rad) {
    return z / focal_px * std::tan(theta_max_rad) + 3.0 * sigma_z_m(model, z, 0.0);
}

}  // namespace rgbd::denoise
