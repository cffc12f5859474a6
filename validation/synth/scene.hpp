// Scene elements around the subject of a synthetic capture (rgbd-synth --floor, --plinth-height-m,
// --walls, --clutter, --people, --scene room; the turntable's platter): triangle soups with a
// plain procedural colour, a segment label per triangle (subject, support, background) and
// their geometry for gt/scene.json, so that object extraction (ground removal, keeping the
// subject) can be scored against known answers (docs/formats.md, gt/; docs/algorithms.md,
// synthetic ground truth). See also: synthesize.hpp (render scene, segment images).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <limits>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "toolkit/point_cloud.hpp"

namespace rgbd::synth {

/// Per-pixel scene labels written to gt/<sensor>/segment/ (docs/formats.md).
enum class SegmentLabel : std::uint8_t {
    kNoReturn = 0,    ///< the noisy depth is invalid
    kSubject = 1,     ///< the clean surface at the pixel is the subject's (gt/mesh.ply)
    kSupport = 2,     ///< floor, plinth or turntable platter
    kBackground = 3,  ///< walls, clutter, people
    kNoSurface = 4,   ///< a valid noisy depth where the clean ray hits nothing (an outlier,
                      ///< flying or jittered pixel against the void)
};

/// Which scene elements surround the subject (ring rig, static subject). Default: none.
struct SceneOptions {
    bool floor = false;            ///< a floor at the floor level, 8 m square (or larger)
    double plinth_height_m = 0.0;  ///< box under the subject, top at its lowest point (0: none)
    int walls = 0;                 ///< 0-4 vertical walls at ring radius + 1 m, 90 deg apart
    int clutter = 0;               ///< boxes and cylinders on the floor level near the ring
    int people = 0;                ///< standing-person boxes outside the ring

    /// Any element at all (false: the render scene is the subject alone, as before).
    bool any() const {
        return floor || plinth_height_m > 0 || walls > 0 || clutter > 0 || people > 0;
    }
    /// Throws InputError naming the field (walls, clutter, people, plinth_height_m).
    void check() const;
    nlohmann::json to_json() const;
};

/// "bare" (nothing) or "room" (floor, 2 walls, 4 clutter items, 1 person); InputError otherwise.
SceneOptions scene_preset(const std::string& name);

/// Kind of a scene element (its shading and its entry in gt/scene.json).
enum class ElementKind { kPlatter, kFloor, kPlinth, kWall, kBox, kCylinder, kPerson };

/// One element of the render scene beyond the subject: triangles [first, end).
struct SceneElement {
    ElementKind kind = ElementKind::kFloor;
    SegmentLabel label = SegmentLabel::kSupport;
    Rgb rgb;  ///< base colour (person: the shirt)
    int first_triangle = 0;
    int end_triangle = 0;
    double base_z = 0.0;      ///< the floor level it stands on (person: trousers below +0.8 m)
    nlohmann::json geometry;  ///< what gt/scene.json says about it (metres, world frame)
};

/// A triangle soup being assembled (world frame, metres).
struct SceneSoup {
    std::vector<Eigen::Vector3d> vertices;
    std::vector<std::array<int, 3>> triangles;
};

/// Everything around the subject, in triangle order after the subject's triangles.
struct Surroundings {
    int object_triangles = -1;  ///< the subject's triangles come first; -1: all are the subject
    std::vector<SceneElement> elements;
    double floor_z = std::numeric_limits<double>::quiet_NaN();  ///< floor level (NaN: none)

    /// The element of triangle t, nullptr for the subject's triangles.
    const SceneElement* element_of(int triangle) const;
    /// kSubject, or the element's label.
    SegmentLabel label_of(int triangle) const;
    /// gt/scene.json's "scene" entry: floor_z and the elements.
    nlohmann::json to_json() const;
};

/// Where the surroundings go: the subject's world bbox, the ring and the sensors (which no
/// element may enclose), and the seed of the clutter and people placement.
struct SceneFrame {
    Eigen::Vector3d subject_lo = Eigen::Vector3d::Zero();
    Eigen::Vector3d subject_hi = Eigen::Vector3d::Zero();
    double ring_radius_m = 1.5;
    std::vector<Eigen::Vector3d> sensor_positions;
    std::uint64_t seed = 1;
};

/// Appends the turntable platter: a dark disc 20 mm thick, radius r_max * 1.25 + 10 mm, its top
/// centre at `top_centre` (label support, flat colour).
void add_platter(SceneSoup& soup, Surroundings& out, const Eigen::Vector3d& top_centre,
                 double r_max);

/// Appends the elements of `options` around the subject (docs/formats.md, gt/scene.json):
/// plinth (top at the subject's lowest point, square footprint 1.2 x the larger horizontal bbox
/// side), floor (at the subject's lowest point - plinth height, side max(8, 2 R + 4) m), walls
/// (2.5 m tall, at R + 1 m from the axis, at 0, 90, 180, 270 deg), clutter (boxes and cylinders
/// of 0.1-0.5 m at 0.6-1.3 R from the axis, >= 0.3 m from the subject's bbox and plinth), people
/// (0.45 x 0.3 x 1.7 m boxes at 1.2-1.6 R facing the axis). Clutter and people keep 0.25 m
/// horizontally from every sensor and from each other. Sets out.floor_z. Throws InputError when
/// a plinth would enclose a sensor, the floor is not below the sensors, or clutter or people
/// find no free place.
void add_surroundings(SceneSoup& soup, Surroundings& out, const SceneOptions& options,
                      const SceneFrame& frame);

/// True colour of a point of element `e` (world frame) whose triangle has the unit normal
/// `normal`: platter flat; floor mid grey with 0.5 m tiles and a fine grain; walls light; boxes,
/// cylinders their colour; people trousers, shirt and head; all but the platter shaded by the
/// normal. Pure function.
Rgb element_color(const SceneElement& e, const Eigen::Vector3d& p_world,
                  const Eigen::Vector3d& normal);

/// The segment image (CV_8UC1, SegmentLabel) of a view: kNoReturn where `noisy_depth` (CV_32FC1)
/// is NaN, else the label of the clean render's triangle at the pixel (`triangle`, CV_32SC1;
/// kNoSurface for -1). Flying pixels, outliers and jittered pixels keep their pixel's label.
cv::Mat segment_image(const cv::Mat& triangle, const cv::Mat& noisy_depth,
                      const Surroundings& surroundings);

}  // namespace rgbd::synth
