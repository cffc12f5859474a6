// PointCloud: a CGAL Point_set_3 plus the metadata of the view it came from (docs/architecture.md,
// the data model; docs/formats.md). Property names equal PLY property names; use the constants
// below.
#pragma once

#include <CGAL/Point_set_3.h>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "toolkit/camera.hpp"
#include "toolkit/pose.hpp"
#include "toolkit/types.hpp"

namespace rgbd {

using PointSet = CGAL::Point_set_3<Point_3, Vector_3>;

/// PLY / Point_set_3 property names. Never spell these as string literals elsewhere.
namespace prop {
inline constexpr const char* kRed = "red";                ///< uint8, sRGB
inline constexpr const char* kGreen = "green";            ///< uint8, sRGB
inline constexpr const char* kBlue = "blue";              ///< uint8, sRGB
inline constexpr const char* kPixel = "pixel";            ///< uint32, row * grid_width + col
inline constexpr const char* kConfidence = "confidence";  ///< float in [0, 1]
inline constexpr const char* kScale = "scale";            ///< float, metres
inline constexpr const char* kView = "view";              ///< int32, id of the source view
inline constexpr const char* kNoise = "noise";            ///< uint8 flag, set by --mark
inline constexpr const char* kSynthetic = "synthetic";    ///< uint8 flag, point not measured
/// uint8 flag: a synthetic point whose colour is what the colour camera saw at its own position
/// (super-resolution's colour-pixel points), unlike the colours a fill invents
inline constexpr const char* kColourPixel = "colour_pixel";
}  // namespace prop

/// Which frame the coordinates of a view are expressed in.
enum class ViewFrame { kSensor, kWorld };

/// Metadata of one view (one PLY document of the stream). Serialised as `comment rgbd:` keys.
struct ViewInfo {
    int id = -1;                              ///< rgbd:view.id (-1 = unset)
    std::string sensor;                       ///< rgbd:view.sensor
    std::optional<std::int64_t> time_ns;      ///< rgbd:view.time_ns, hub time
    std::optional<std::int64_t> frame_index;  ///< rgbd:view.frame_index, index in frames.csv
    ViewFrame frame = ViewFrame::kSensor;     ///< rgbd:view.frame
    std::optional<PinholeIntrinsics>
        intrinsics;                         ///< rgbd:camera.intrinsics (+ distortion), depth camera
    std::optional<Pose> world_from_sensor;  ///< rgbd:pose.world_from_sensor
    int grid_width = 0;                     ///< rgbd:grid w h (0 = not organised)
    int grid_height = 0;
    std::string source;                ///< rgbd:view.source, path of the source frame
    std::vector<std::string> history;  ///< rgbd:history lines, oldest first
    /// Unknown rgbd: keys and foreign comments, verbatim (without "comment "), kept in order.
    std::vector<std::string> extra_comments;

    bool has_grid() const { return grid_width > 0 && grid_height > 0; }
};

/// 8-bit sRGB colour.
struct Rgb {
    std::uint8_t r = 0, g = 0, b = 0;
    bool operator==(const Rgb&) const = default;
};

/// A view: points with optional properties, plus its ViewInfo.
struct PointCloud {
    PointSet points;
    ViewInfo view;

    using Uint8Map = PointSet::Property_map<std::uint8_t>;
    using Uint32Map = PointSet::Property_map<std::uint32_t>;
    using Int32Map = PointSet::Property_map<std::int32_t>;
    using FloatMap = PointSet::Property_map<float>;

    /// The three colour maps; valid only if has_colors().
    struct ColorMaps {
        Uint8Map r, g, b;
        Rgb get(PointSet::Index i) const { return {r[i], g[i], b[i]}; }
        void set(PointSet::Index i, Rgb c) const {
            r[i] = c.r;
            g[i] = c.g;
            b[i] = c.b;
        }
    };

    std::size_t size() const { return points.size(); }
    bool empty() const { return points.empty(); }

    bool has_colors() const;
    /// Adds (or returns existing) red/green/blue maps, default black.
    ColorMaps add_colors();
    /// Throws std::logic_error when absent.
    ColorMaps colors() const;

    /// Adds (or returns) a uint8 flag map such as prop::kNoise or prop::kSynthetic.
    Uint8Map add_flag(const char* name);
    std::optional<Uint8Map> flag(const char* name) const;
    Uint32Map add_pixel_map();
    std::optional<Uint32Map> pixel_map() const;
    FloatMap add_float(const char* name, float default_value = 0.0f);
    std::optional<FloatMap> float_map(const char* name) const;
    Int32Map add_view_map();
    std::optional<Int32Map> view_map() const;

    /// Names of all properties besides "point" and "normal", in Point_set_3 order.
    std::vector<std::string> property_names() const;
};

/// Applies a rigid transform to points and normals in place.
void transform(PointCloud& cloud, const Pose& target_from_source);

/// Brings a sensor-frame view into the world frame with its world_from_sensor pose (no-op
/// for a view already in the world frame). Throws InputError when the pose is missing.
void to_world_frame(PointCloud& cloud);

}  // namespace rgbd
