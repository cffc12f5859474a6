// Synthetic RGB-D captures with ground truth ("virtual ring", docs/algorithms.md, synthetic ground
// truth): places a mesh in the world, builds a ring of Kinect v2 sensors or one SR300-like sensor
// in front of a turntable, renders depth and colour by rasterisation, injects sensor noise,
// calibration error and clock offsets, and writes a capture folder v1 with gt/ (docs/formats.md,
// §6). See also: rasterizer.hpp, noise.hpp, texture.hpp, validation/rgbd_synth.cpp (the tool).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "io/capture_folder.hpp"
#include "toolkit/mesh.hpp"
#include "toolkit/pose.hpp"
#include "toolkit/progress.hpp"
#include "validation/synth/noise.hpp"
#include "validation/synth/rasterizer.hpp"
#include "validation/synth/scene.hpp"
#include "validation/synth/texture.hpp"

namespace rgbd::synth {

/// The virtual rig.
enum class RigKind {
    kRing,       ///< N Kinect v2 on a horizontal ring, all looking at the object centre
    kTurntable,  ///< one SR300-like sensor, the object rotated in stops on a turntable
};

/// Up axis of the input mesh.
enum class UpAxis { kY, kZ };

/// A moving subject (issue 20, 3D video): the object turns or nods rigidly over the frame sets.
enum class MotionKind {
    kNone,  ///< static scene, fresh noise per frame set
    kTurn,  ///< about the vertical axis through the object centre, motion_deg degrees per second
    kNod,   ///< about the horizontal world x axis through the object centre, motion_deg * sin(2 pi
            ///< t / motion_period_s)
};

/// Everything that defines a synthetic capture. Defaults are the captures of the peer comparisons.
struct SynthOptions {
    RigKind rig = RigKind::kRing;  ///< ring or turntable
    int sensors = 8;               ///< ring: number of sensors, 360/N degrees apart
    double ring_radius_m = 1.5;    ///< ring: horizontal distance of the sensors from the axis
    double ring_height_m = 1.6;    ///< height of the ring (world z); the object centre sits at
                                   ///< ring_height_m - ring_radius_m tan(tilt_deg) on the z axis
    double tilt_deg = 10.0;        ///< down-tilt of every sensor, degrees
    double turntable_distance_m = 0.55;  ///< turntable: horizontal distance sensor-axis
    int turntable_stops = 12;            ///< turntable: number of stops
    double turntable_step_deg = 30.0;    ///< turntable: nominal rotation per stop
    double axis_tilt_deg = 1.5;          ///< turntable truth: tilt of the true rotation axis
    double axis_shift_mm = 15.0;         ///< turntable truth: horizontal shift of the axis
    double angle_noise_deg = 0.2;        ///< turntable truth: std of each stop's angle error
    bool stand = false;                  ///< turntable: render the platter the object stands on
                                         ///< (a dark disc, not in gt/mesh.ply)
    double resolution_scale = 1.0;       ///< multiplies the sensors' pixel counts per side
                                         ///< (intrinsics scaled alike; < 1 for fast tests)
    double height_m = 0.45;              ///< the mesh is scaled to this height (bbox, up axis)
    UpAxis up = UpAxis::kY;              ///< up axis of the input mesh
    NoiseOptions noise;                  ///< sensor noise (NoiseOptions::none() = clean)
    double calib_error_deg = 1.5;        ///< rig.json rotation error per sensor (sensor 0 exact)
    double calib_error_mm = 15.0;        ///< rig.json translation error per sensor (sensor 0 exact)
    double clock_offset_max_ms = 500.0;  ///< clock offsets uniform in [-max, max] per sensor
    int frames = 1;                      ///< frame sets (turntable: frames per stop)
    double frame_period_s = 1.0 / 30.0;  ///< time between frame sets
    MotionKind motion = MotionKind::kNone;  ///< ring: the object moves over the frame sets
    double motion_deg = 90.0;               ///< turn: degrees per second; nod: amplitude, degrees
    double motion_period_s = 2.0;           ///< nod: period, seconds
    std::uint64_t seed = 1;                 ///< seeds every random choice
    TextureOptions texture;                 ///< procedural colour
    SceneOptions scene;  ///< ring, static subject: floor, plinth, walls, clutter, people (none)
    Rgb background{64, 64, 64};  ///< colour where the colour camera sees no object
    std::string mesh_source;     ///< provenance written to gt/scene.json (free text)

    /// Throws InputError on absurd values.
    void check() const;
    nlohmann::json to_json() const;
};

/// The object's rigid motion at frame set `set` (identity at set 0): p_world(set) =
/// object_motion(...) * p_world(0), a rotation about an axis through `centre`.
Pose object_motion(const SynthOptions& options, int set, const Eigen::Vector3d& centre);
/// "none" / "turn" / "nod" (InputError on others).
MotionKind parse_motion_kind(const std::string& name);

/// "ring" / "turntable", "y" / "z"; parse functions throw InputError on unknown names.
std::string to_string(RigKind rig);
RigKind parse_rig_kind(const std::string& name);
UpAxis parse_up_axis(const std::string& name);

/// Kinect v2 (docs/algorithms.md, synthetic ground truth) and SR300-like sensor specs with
/// identity poses and zero clock offset.
io::SensorSpec kinect_v2_spec(const std::string& id);
io::SensorSpec sr300_spec(const std::string& id);
/// Noise traits (model, range, quantum) for a spec made by the functions above.
DepthSensorTraits traits_of(const io::SensorSpec& spec);

/// Camera pose at a position looking at a target (toolkit/pose.hpp).
using rgbd::look_at;

/// The input mesh scaled and placed in the world (z up, bbox centre at `centre`).
struct PlacedMesh {
    Mesh mesh;                                  ///< world frame, metres
    double scale = 1.0;                         ///< metres per input unit
    Eigen::Vector3d input_centre;               ///< bbox centre of the input mesh (input units)
    Eigen::Vector3d centre;                     ///< bbox centre in the world = object-frame origin
    Eigen::Matrix3d world_from_input_rotation;  ///< up-axis rotation
    /// The render scene beyond the object: its triangles come first, then the platter or the
    /// scene elements (surroundings.object_triangles = -1: all are the object's).
    Surroundings surroundings;
    /// Object frame (texture frame): world translated so that the centre is the origin.
    Eigen::Vector3d object_from_world(const Eigen::Vector3d& p_world) const {
        return p_world - centre;
    }
};

/// Scales `input` to `height_m` along its up axis and places its bbox centre at `centre`
/// with the up axis along world z. Throws InputError for an empty or flat mesh.
PlacedMesh place_mesh(const Mesh& input, double height_m, UpAxis up, const Eigen::Vector3d& centre);

/// One sensor of the virtual rig: what rig.json says and the truth.
struct SyntheticSensor {
    io::SensorSpec spec;  ///< as written to rig.json (pose with calibration error, clock offset)
    DepthSensorTraits traits;
    /// True world_from_depth per frame index (ring: the same pose for every frame).
    std::vector<Pose> true_world_from_depth;
    /// Nominal per-frame poses written to frames.csv (turntable only; empty for the ring).
    std::vector<Pose> nominal_world_from_depth;
    /// Frame index -> hub time, ns.
    std::vector<std::int64_t> hub_time_ns;
};

/// The virtual rig for `options` (deterministic in options.seed).
struct SyntheticRig {
    std::vector<SyntheticSensor> sensors;
    Eigen::Vector3d object_centre;  ///< where every sensor looks, world frame
    bool per_frame_poses = false;   ///< turntable
    int frames_per_sensor = 1;
};
SyntheticRig make_rig(const SynthOptions& options);

/// The render scene of `placed` standing on a turntable platter: a dark disc 20 mm thick,
/// 1.25 times the object's horizontal radius + 10 mm, its top at the object's lowest point,
/// centred below the object; it turns with the object and is not part of the ground truth.
/// Sets placed.surroundings.
RenderScene scene_with_platter(PlacedMesh& placed);

/// The render scene of a capture: the object alone (RenderScene(placed.mesh), as without scene
/// elements), with the platter (options.stand), or with the scene elements of options.scene
/// around it (scene.hpp; the rig's sensors are kept out of them). Sets placed.surroundings.
RenderScene make_render_scene(PlacedMesh& placed, const SynthOptions& options,
                              const SyntheticRig& rig);

/// One rendered view.
struct RenderedView {
    DepthRender clean;  ///< noise-free render, depth camera (metres, normals, triangle ids)
    NoisyDepth noisy;   ///< depth with noise and labels
    cv::Mat color;      ///< CV_8UC3 BGR, colour camera, with colour noise (before JPEG)
    cv::Mat segment;    ///< CV_8UC1 SegmentLabel per depth pixel (segment_image, scene.hpp)
};

/// Renders one view of `scene` by a sensor whose depth camera is at `world_from_depth`;
/// the colour camera sits at world_from_depth * color_from_depth^-1 and renders its own
/// visibility. `seed` selects the noise. Triangles beyond the object's are shaded and labelled
/// by placed.surroundings.
RenderedView render_view(const RenderScene& scene, const PlacedMesh& placed,
                         const io::SensorSpec& spec, const DepthSensorTraits& traits,
                         const Pose& world_from_depth, const SynthOptions& options,
                         std::uint64_t seed);

/// What synthesize_capture did.
struct SynthSummary {
    int sensors = 0;
    int frames = 0;                    ///< frame sets written
    int views = 0;                     ///< depth frames written
    std::vector<long> valid_points;    ///< valid noisy depth pixels per view, in write order
    std::vector<long> surface_points;  ///< of which labelled surface
    double render_s = 0;               ///< rendering + noise
    double total_s = 0;                ///< including writing
};

/// Writes a complete synthetic capture of `mesh` (input units, `options.up` up) to `out_dir`,
/// which must not exist or be empty. Everything is written into a temporary sibling folder
/// that is renamed at the end, so a failure leaves nothing behind (io::write_folder_atomic).
/// Throws InputError (bad options) or IoError (non-empty folder, naming the file).
SynthSummary synthesize_capture(const Mesh& mesh, const std::filesystem::path& out_dir,
                                const SynthOptions& options, const Progress& progress = {});

/// 4x4 row-major JSON array of a pose.
nlohmann::json pose_to_json(const Pose& pose);

}  // namespace rgbd::synth
