#include "validation/synth/synthesize.hpp"

#include <CGAL/bounding_box.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <opencv2/imgproc.hpp>

#include "io/mesh_io.hpp"
#include "io/output_file.hpp"
#include "toolkit/error.hpp"
#include "toolkit/report.hpp"
#include "validation/synth/random.hpp"

namespace rgbd::synth {
namespace {

namespace fs = std::filesystem;
constexpr double kDeg = std::numbers::pi / 180.0;
constexpr std::int64_t kBaseTimeNs = 1'000'000'000;    // hub time of the first frame set
constexpr std::int64_t kStopPeriodNs = 2'000'000'000;  // turntable: time between stops

// Seed purposes.
enum SeedTag : std::uint64_t { kRigSeed = 1, kDepthSeed = 2, kColorSeed = 3 };

Eigen::Vector3d random_unit(const CounterRandom& rng, std::uint64_t stream, std::uint64_t i) {
    const double z = 2.0 * rng.uniform(stream, i) - 1.0;
    const double phi = 2.0 * std::numbers::pi * rng.uniform(stream + 100, i);
    const double s = std::sqrt(std::max(0.0, 1.0 - z * z));
    return {s * std::cos(phi), s * std::sin(phi), z};
}

Pose rotation_about(const Eigen::Vector3d& point, const Eigen::Vector3d& axis, double angle) {
    Pose p = Pose::Identity();
    p.linear() = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
    p.translation() = point - p.linear() * point;
    return p;
}

std::string frame_name(std::int64_t index, const char* ext) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%06lld.%s", static_cast<long long>(index), ext);
    return buf;
}

/// Depth in metres (NaN = none) -> uint16 in depth_scale units; out-of-range values -> 0.
cv::Mat to_depth16(const cv::Mat& depth_m, double depth_scale) {
    cv::Mat out(depth_m.size(), CV_16UC1);
    for (int r = 0; r < depth_m.rows; ++r)
        for (int c = 0; c < depth_m.cols; ++c) {
            const double z =
                depth_m.type() == CV_64FC1 ? depth_m.at<double>(r, c) : depth_m.at<float>(r, c);
            const double v = std::isfinite(z) ? std::round(z * depth_scale) : 0.0;
            out.at<std::uint16_t>(r, c) =
                v > 0 && v <= 65535 ? static_cast<std::uint16_t>(v) : std::uint16_t{0};
        }
    return out;
}

/// Scales a camera's pixel grid by `f` per side (intrinsics in pixels alike, pixel centres
/// kept: c' = (c + 0.5) f - 0.5).
void scale_camera(PinholeIntrinsics& c, double f) {
    if (f == 1.0) return;
    c.width = std::max(1, static_cast<int>(std::lround(c.width * f)));
    c.height = std::max(1, static_cast<int>(std::lround(c.height * f)));
    c.fx *= f;
    c.fy *= f;
    c.cx = (c.cx + 0.5) * f - 0.5;
    c.cy = (c.cy + 0.5) * f - 0.5;
}

}  // namespace

// ---------------------------------------------------------------- options

void SynthOptions::check() const {
    check_range("number of sensors", sensors, Range::closed(1, 64));
    check_range("ring radius", ring_radius_m, Range::open(0.1, 100), "m");
    RGBD_CHECK(std::isfinite(ring_height_m) && std::abs(ring_height_m) < 100,
               "ring height must be finite and below 100 m");
    check_range("tilt", tilt_deg, Range::open(-80, 80), "deg");
    check_range("turntable distance", turntable_distance_m, Range::open(0.05, 100), "m");
    check_range("turntable stops", turntable_stops, Range::closed(1, 3600));
    RGBD_CHECK(std::isfinite(turntable_step_deg), "turntable step must be finite");
    check_range("axis tilt", axis_tilt_deg, Range::closed(-45, 45), "deg");
    check_range("axis shift", axis_shift_mm, Range::closed(0, 1000), "mm");
    check_range("angle noise", angle_noise_deg, Range::closed(0, 45), "deg");
    RGBD_CHECK(!stand || rig == RigKind::kTurntable, "a stand needs the turntable rig");
    check_range("resolution scale", resolution_scale, Range::closed(0.1, 4));
    check_range("object height", height_m, Range::open_closed(0.001, 100), "m");
    noise.check();
    check_range("calibration rotation error", calib_error_deg, Range::closed(0, 180), "deg");
    check_range("calibration translation error", calib_error_mm, Range::closed(0, 10000), "mm");
    check_range("clock offset", clock_offset_max_ms, Range::closed(0, 3.6e6), "ms");
    check_range("frames", frames, Range::closed(1, 100000));
    check_range("frame period", frame_period_s, Range::open(0, 3600), "s");
    texture.check();
    RGBD_CHECK(motion == MotionKind::kNone || rig == RigKind::kRing,
               "a moving object needs the ring rig");
    scene.check();
    RGBD_CHECK(!scene.any() || rig == RigKind::kRing,
               "scene elements (--floor, --plinth-height-m, --walls, --clutter, --people, --scene "
               "room) need --rig ring");
    RGBD_CHECK(!scene.any() || motion == MotionKind::kNone,
               "scene elements (--floor, --plinth-height-m, --walls, --clutter, --people, --scene "
               "room) need a static object (--motion none)");
    check_range("motion_deg (degrees per second for a turn, amplitude for a nod)", motion_deg,
                Range::closed(-3600, 3600));
    check_range("motion period", motion_period_s, Range::open(0, 3600), "s");
}

MotionKind parse_motion_kind(const std::string& name) {
    if (name == "none") return MotionKind::kNone;
    if (name == "turn") return MotionKind::kTurn;
    if (name == "nod") return MotionKind::kNod;
    throw InputError("unknown motion '" + name + "' (expected none, turn or nod)");
}

Pose object_motion(const SynthOptions& o, int set, const Eigen::Vector3d& centre) {
    const double t = set * o.frame_period_s;
    double angle_deg = 0;
    Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
    if (o.motion == MotionKind::kTurn) {
        angle_deg = o.motion_deg * t;
    } else if (o.motion == MotionKind::kNod) {
        angle_deg = o.motion_deg * std::sin(2.0 * std::numbers::pi * t / o.motion_period_s);
        axis = Eigen::Vector3d::UnitX();
    }
    Pose m = Pose::Identity();
    m.linear() = Eigen::AngleAxisd(angle_deg * std::numbers::pi / 180.0, axis).toRotationMatrix();
    m.translation() = centre - m.linear() * centre;
    return m;
}

nlohmann::json SynthOptions::to_json() const {
    return {{"rig", to_string(rig)},
            {"sensors", sensors},
            {"ring_radius_m", ring_radius_m},
            {"ring_height_m", ring_height_m},
            {"tilt_deg", tilt_deg},
            {"turntable_distance_m", turntable_distance_m},
            {"turntable_stops", turntable_stops},
            {"turntable_step_deg", turntable_step_deg},
            {"axis_tilt_deg", axis_tilt_deg},
            {"axis_shift_mm", axis_shift_mm},
            {"angle_noise_deg", angle_noise_deg},
            {"resolution_scale", resolution_scale},
            {"stand", stand},
            {"height_m", height_m},
            {"up", up == UpAxis::kY ? "y" : "z"},
            {"calib_error_deg", calib_error_deg},
            {"calib_error_mm", calib_error_mm},
            {"clock_offset_max_ms", clock_offset_max_ms},
            {"frames", frames},
            {"frame_period_s", frame_period_s},
            {"motion", motion == MotionKind::kNone   ? "none"
                       : motion == MotionKind::kTurn ? "turn"
                                                     : "nod"},
            {"motion_deg", motion_deg},
            {"motion_period_s", motion_period_s},
            {"seed", seed},
            {"background_rgb", {background.r, background.g, background.b}}};
}

std::string to_string(RigKind rig) { return rig == RigKind::kRing ? "ring" : "turntable"; }

RigKind parse_rig_kind(const std::string& name) {
    if (name == "ring") return RigKind::kRing;
    if (name == "turntable") return RigKind::kTurntable;
    throw InputError("unknown rig '" + name + "' (expected ring or turntable)");
}

UpAxis parse_up_axis(const std::string& name) {
    if (name == "y") return UpAxis::kY;
    if (name == "z") return UpAxis::kZ;
    throw InputError("unknown up axis '" + name + "' (expected y or z)");
}

// ---------------------------------------------------------------- sensors and rig

namespace {

/// A sensor of the synthetic rigs: `model` names it and its noise model; colour_offset_m is
/// the colour camera's position in the depth camera's frame (no rotation between them).
io::SensorSpec synthetic_spec(const std::string& id, const std::string& model,
                              const PinholeIntrinsics& depth, const PinholeIntrinsics& color,
                              double depth_scale, double range_min_m, double range_max_m,
                              const Eigen::Vector3d& colour_offset_m) {
    io::SensorSpec s;
    s.id = id;
    s.model = model;
    s.depth = depth;
    s.color = color;
    s.depth_scale = depth_scale;
    s.range_min_m = range_min_m;
    s.range_max_m = range_max_m;
    s.color_from_depth = Pose::Identity();
    s.color_from_depth.translation() = colour_offset_m;
    s.noise_model = model;
    return s;
}

}  // namespace

io::SensorSpec kinect_v2_spec(const std::string& id) {
    return synthetic_spec(
        id, "kinect_v2",
        {.width = 512, .height = 424, .fx = 365.5, .fy = 365.5, .cx = 256.0, .cy = 212.0},
        {.width = 1920, .height = 1080, .fx = 1081.37, .fy = 1081.37, .cx = 959.5, .cy = 539.5},
        1000.0, 0.5, 4.5, Eigen::Vector3d(0.052, 0, 0));
}

io::SensorSpec sr300_spec(const std::string& id) {
    return synthetic_spec(
        id, "sr300",
        {.width = 640, .height = 480, .fx = 475.9, .fy = 475.9, .cx = 310.7, .cy = 245.2},
        {.width = 1920, .height = 1080, .fx = 1386.0, .fy = 1386.0, .cx = 959.5, .cy = 539.5},
        8000.0 /* 1/8 mm */, 0.2, 1.5, Eigen::Vector3d(0.0257, -0.00073, 0.00394));
}

DepthSensorTraits traits_of(const io::SensorSpec& spec) {
    DepthSensorTraits t;
    t.model = spec.noise_model == "sr300" ? DepthNoiseModel::kSr300 : DepthNoiseModel::kKinectV2;
    t.range_min_m = spec.range_min_m;
    t.range_max_m = spec.range_max_m;
    t.quantum_m = 1.0 / spec.depth_scale;
    return t;
}

PlacedMesh place_mesh(const Mesh& input, double height_m, UpAxis up,
                      const Eigen::Vector3d& centre) {
    RGBD_CHECK(input.number_of_vertices() > 0 && input.number_of_faces() > 0,
               "cannot place an empty mesh");
    RGBD_CHECK(std::isfinite(height_m) && height_m > 0, "object height must be > 0");
    PlacedMesh out;
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Vector3d hi = -lo;
    for (const auto v : input.vertices()) {
        const Eigen::Vector3d p = to_eigen(input.point(v));
        RGBD_CHECK(p.allFinite(), "mesh has non-finite vertex coordinates");
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
    }
    const int up_index = up == UpAxis::kY ? 1 : 2;
    const double extent = hi[up_index] - lo[up_index];
    RGBD_CHECK(extent > 0, "mesh is flat along its up axis");
    out.scale = height_m / extent;
    out.input_centre = 0.5 * (lo + hi);
    out.centre = centre;
    out.world_from_input_rotation =
        up == UpAxis::kY
            ? Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitX()).toRotationMatrix()
            : Eigen::Matrix3d::Identity();
    out.mesh = input;
    for (const auto v : out.mesh.vertices()) {
        const Eigen::Vector3d p = to_eigen(out.mesh.point(v));
        out.mesh.point(v) =
            to_point(out.world_from_input_rotation * (out.scale * (p - out.input_centre)) + centre);
    }
    return out;
}

SyntheticRig make_rig(const SynthOptions& o) {
    o.check();
    SyntheticRig rig;
    const CounterRandom rng(derive_seed(o.seed, kRigSeed));
    const double tilt = o.tilt_deg * kDeg;
    rig.object_centre = Eigen::Vector3d(0, 0, o.ring_height_m - o.ring_radius_m * std::tan(tilt));
    const auto clock_offset = [&](int i) {
        const double ms = (2.0 * rng.uniform(10, i) - 1.0) * o.clock_offset_max_ms;
        return static_cast<std::int64_t>(std::llround(ms * 1e6));
    };
    const std::int64_t period_ns = std::llround(o.frame_period_s * 1e9);

    if (o.rig == RigKind::kRing) {
        rig.frames_per_sensor = o.frames;
        for (int i = 0; i < o.sensors; ++i) {
            SyntheticSensor s;
            s.spec = kinect_v2_spec("k2-" + std::to_string(i));
            scale_camera(s.spec.depth, o.resolution_scale);
            scale_camera(s.spec.color, o.resolution_scale);
            s.traits = traits_of(s.spec);
            const double phi = 2.0 * std::numbers::pi * i / o.sensors;
            const Eigen::Vector3d pos(o.ring_radius_m * std::cos(phi),
                                      o.ring_radius_m * std::sin(phi), o.ring_height_m);
            const Pose truth = look_at(pos, rig.object_centre);
            Pose delta = Pose::Identity();
            if (i > 0) {  // sensor 0 exact
                delta.linear() = Eigen::AngleAxisd(o.calib_error_deg * kDeg, random_unit(rng, 1, i))
                                     .toRotationMatrix();
                delta.translation() = 1e-3 * o.calib_error_mm * random_unit(rng, 2, i);
            }
            s.spec.world_from_depth = truth * delta;
            s.spec.clock_offset_ns = clock_offset(i);
            s.true_world_from_depth.assign(o.frames, truth);
            for (int f = 0; f < o.frames; ++f) s.hub_time_ns.push_back(kBaseTimeNs + f * period_ns);
            rig.sensors.push_back(std::move(s));
        }
        return rig;
    }

    // Turntable: the world is the object frame at stop 0; the static camera therefore moves
    // around the object by the inverse of each stop's turntable motion.
    rig.per_frame_poses = true;
    rig.frames_per_sensor = o.turntable_stops * o.frames;
    SyntheticSensor s;
    s.spec = sr300_spec("sr300-0");
    scale_camera(s.spec.depth, o.resolution_scale);
    scale_camera(s.spec.color, o.resolution_scale);
    s.traits = traits_of(s.spec);
    const double d = o.turntable_distance_m;
    const Pose camera =
        look_at(rig.object_centre + Eigen::Vector3d(d, 0, d * std::tan(tilt)), rig.object_centre);
    s.spec.world_from_depth = camera;
    s.spec.clock_offset_ns = clock_offset(0);
    const double az_axis = 2.0 * std::numbers::pi * rng.uniform(20, 0);
    const double az_shift = 2.0 * std::numbers::pi * rng.uniform(21, 0);
    const double at = o.axis_tilt_deg * kDeg;
    const Eigen::Vector3d axis(std::sin(at) * std::cos(az_axis), std::sin(at) * std::sin(az_axis),
                               std::cos(at));
    const Eigen::Vector3d axis_point =
        rig.object_centre +
        1e-3 * o.axis_shift_mm * Eigen::Vector3d(std::cos(az_shift), std::sin(az_shift), 0);
    for (int k = 0; k < o.turntable_stops; ++k) {
        const double nominal = k * o.turntable_step_deg * kDeg;
        const double truth = k == 0 ? 0.0 : nominal + o.angle_noise_deg * kDeg * rng.normal(22, k);
        const Pose object_nominal =
            rotation_about(rig.object_centre, Eigen::Vector3d::UnitZ(), nominal);
        const Pose object_true = rotation_about(axis_point, axis, truth);
        for (int f = 0; f < o.frames; ++f) {
            s.nominal_world_from_depth.push_back(object_nominal.inverse() * camera);
            s.true_world_from_depth.push_back(object_true.inverse() * camera);
            s.hub_time_ns.push_back(kBaseTimeNs + k * kStopPeriodNs + f * period_ns);
        }
    }
    rig.sensors.push_back(std::move(s));
    return rig;
}

// ---------------------------------------------------------------- rendering

RenderedView render_view(const RenderScene& scene, const PlacedMesh& placed,
                         const io::SensorSpec& spec, const DepthSensorTraits& traits,
                         const Pose& world_from_depth, const SynthOptions& options,
                         std::uint64_t seed) {
    RenderedView v;
    v.clean = render_depth(scene, spec.depth, world_from_depth);
    v.noisy = apply_depth_noise(v.clean, spec.depth, traits, options.noise,
                                derive_seed(seed, kDepthSeed));
    const Pose world_from_color = world_from_depth * spec.color_from_depth.inverse();
    const TextureOptions texture = options.texture;
    v.color = render_color(
        scene, spec.color, world_from_color,
        [&placed, &scene, texture](const Eigen::Vector3d& p_world, int triangle) {
            if (const SceneElement* e = placed.surroundings.element_of(triangle))
                return element_color(*e, p_world, scene.normals()[triangle]);
            return texture_color(placed.object_from_world(p_world), texture);
        },
        options.background);
    apply_color_noise(v.color, options.noise.color_sigma, derive_seed(seed, kColorSeed));
    v.segment = segment_image(v.clean.triangle, v.noisy.depth, placed.surroundings);
    return v;
}

nlohmann::json pose_to_json(const Pose& pose) {
    nlohmann::json m = nlohmann::json::array();
    const Eigen::Matrix4d a = pose.matrix();
    for (int r = 0; r < 4; ++r) m.push_back({a(r, 0), a(r, 1), a(r, 2), a(r, 3)});
    return m;
}

// ---------------------------------------------------------------- capture

RenderScene scene_with_platter(PlacedMesh& placed) {
    const RenderScene object(placed.mesh);
    SceneSoup soup{object.vertices(), object.triangles()};
    placed.surroundings = Surroundings{};
    placed.surroundings.object_triangles = static_cast<int>(soup.triangles.size());
    double z_min = std::numeric_limits<double>::infinity(), r_max = 0;
    for (const auto& p : soup.vertices) {
        z_min = std::min(z_min, p.z());
        r_max = std::max(r_max, (p - placed.centre).head<2>().norm());
    }
    add_platter(soup, placed.surroundings,
                Eigen::Vector3d(placed.centre.x(), placed.centre.y(), z_min), r_max);
    return RenderScene(std::move(soup.vertices), std::move(soup.triangles));
}

RenderScene make_render_scene(PlacedMesh& placed, const SynthOptions& o, const SyntheticRig& rig) {
    o.check();
    placed.surroundings = Surroundings{};
    if (o.stand) return scene_with_platter(placed);
    if (!o.scene.any()) return RenderScene(placed.mesh);
    const RenderScene object(placed.mesh);
    SceneSoup soup{object.vertices(), object.triangles()};
    placed.surroundings.object_triangles = static_cast<int>(soup.triangles.size());
    SceneFrame frame;
    frame.subject_lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    frame.subject_hi = -frame.subject_lo;
    for (const auto& p : soup.vertices) {
        frame.subject_lo = frame.subject_lo.cwiseMin(p);
        frame.subject_hi = frame.subject_hi.cwiseMax(p);
    }
    frame.ring_radius_m = o.ring_radius_m;
    for (const auto& s : rig.sensors)
        for (const auto& pose : s.true_world_from_depth)
            frame.sensor_positions.push_back(pose.translation());
    frame.seed = o.seed;
    add_surroundings(soup, placed.surroundings, o.scene, frame);
    return RenderScene(std::move(soup.vertices), std::move(soup.triangles));
}

namespace {

void write_capture(const Mesh& mesh, const fs::path& root, const SynthOptions& o,
                   const Progress& progress, SynthSummary& summary) {
    const Stopwatch total;
    const SyntheticRig rig = make_rig(o);
    PlacedMesh placed = place_mesh(mesh, o.height_m, o.up, rig.object_centre);
    const RenderScene scene = make_render_scene(placed, o, rig);

    io::Rig rig_json;
    for (const auto& s : rig.sensors) rig_json.sensors.push_back(s.spec);
    rig_json.extra["generator"] = "rgbd-synth";
    io::CaptureWriter writer(root, rig_json);

    const fs::path gt = root / "gt";
    for (const auto& s : rig.sensors) {
        fs::create_directories(gt / s.spec.id / "depth_clean");
        fs::create_directories(gt / s.spec.id / "labels");
        fs::create_directories(gt / s.spec.id / "segment");
    }
    const int nsensors = static_cast<int>(rig.sensors.size());
    const int nsets = rig.frames_per_sensor;
    summary.sensors = nsensors;
    for (int set = 0; set < nsets; ++set) {
        std::vector<RenderedView> views(nsensors);
        const Stopwatch render;
        // A moving object is rendered by moving the sensors the other way (the texture stays
        // on the object); rig.json and the recorded poses keep the fixed sensors.
        const Pose object_from_moved = object_motion(o, set, placed.centre).inverse();
        tbb::parallel_for(0, nsensors, [&](int i) {
            const auto& s = rig.sensors[i];
            views[i] = render_view(scene, placed, s.spec, s.traits,
                                   object_from_moved * s.true_world_from_depth[set], o,
                                   derive_seed(o.seed, 100 + i, set));
        });
        summary.render_s += render.seconds();
        // Ground-truth images in parallel (distinct files), capture files in order.
        tbb::parallel_for(0, nsensors, [&](int i) {
            const auto& s = rig.sensors[i];
            cv::Mat clean = views[i].clean.depth.clone();
            clean.setTo(std::numeric_limits<double>::quiet_NaN(),
                        (clean < s.spec.range_min_m) | (clean > s.spec.range_max_m));
            io::write_image_atomic(gt / s.spec.id / "depth_clean" / frame_name(set, "png"),
                                   to_depth16(clean, s.spec.depth_scale));
            io::write_image_atomic(gt / s.spec.id / "labels" / frame_name(set, "png"),
                                   views[i].noisy.labels);
            io::write_image_atomic(gt / s.spec.id / "segment" / frame_name(set, "png"),
                                   views[i].segment);
        });
        io::FrameSet fs_line;
        fs_line.set = set;
        fs_line.time_ns = rig.sensors[0].hub_time_ns[set];
        fs_line.spread_ns = 0;
        for (int i = 0; i < nsensors; ++i) {
            const auto& s = rig.sensors[i];
            std::optional<Pose> pose;
            if (rig.per_frame_poses) pose = s.nominal_world_from_depth[set];
            writer.add_frame(s.spec.id, set, s.hub_time_ns[set] + s.spec.clock_offset_ns,
                             views[i].noisy.depth, views[i].color, pose);
            fs_line.frames.push_back(set);
            const cv::Mat& d = views[i].noisy.depth;
            summary.valid_points.push_back(cv::countNonZero(d == d));
            summary.surface_points.push_back(
                cv::countNonZero(views[i].noisy.labels == static_cast<int>(PixelLabel::kSurface)));
        }
        writer.add_frameset(fs_line);
        summary.views += nsensors;
        ++summary.frames;
        if (!report_progress(progress, double(set + 1) / nsets)) throw AlgorithmError("cancelled");
    }

    // Ground truth.
    nlohmann::json poses = nlohmann::json::object();
    nlohmann::json clock = {{"reference", "hub"},
                            {"definition", "time_ns in frames.csv = hub time + offset_ns"},
                            {"sensors", nlohmann::json::object()}};
    for (const auto& s : rig.sensors) {
        if (rig.per_frame_poses) {
            nlohmann::json per = nlohmann::json::object();
            for (std::size_t f = 0; f < s.true_world_from_depth.size(); ++f)
                per[std::to_string(f)] = pose_to_json(s.true_world_from_depth[f]);
            poses[s.spec.id] = per;
        } else {
            poses[s.spec.id] = pose_to_json(s.true_world_from_depth.front());
        }
        clock["sensors"][s.spec.id] = {{"offset_ns", s.spec.clock_offset_ns}, {"drift_ppm", 0.0}};
    }
    io::write_text_atomic(gt / "world_from_depth.json", poses.dump(2) + "\n");
    io::write_text_atomic(gt / "clock.json", clock.dump(2) + "\n");
    if (o.motion != MotionKind::kNone) {
        nlohmann::json per = nlohmann::json::object();
        for (int set = 0; set < nsets; ++set)
            per[std::to_string(set)] = pose_to_json(object_motion(o, set, placed.centre));
        const nlohmann::json motion = {
            {"kind", o.motion == MotionKind::kTurn ? "turn" : "nod"},
            {"deg", o.motion_deg},
            {"period_s", o.motion_period_s},
            {"definition",
             "the object at frame set k: p_world = world_from_mesh[k] * p, p a "
             "vertex of gt/mesh.ply (the object at set 0)"},
            {"world_from_mesh", per}};
        io::write_text_atomic(gt / "motion.json", motion.dump(2) + "\n");
    }
    Pose world_from_object = Pose::Identity();
    world_from_object.translation() = placed.centre;
    nlohmann::json scene_json = {
        {"format", "rgbd-synth"},
        {"version", 1},
        {"units", "m"},
        {"mesh",
         {{"source", o.mesh_source},
          {"file", "gt/mesh.ply"},
          {"scale_m_per_unit", placed.scale},
          {"input_bbox_centre",
           {placed.input_centre.x(), placed.input_centre.y(), placed.input_centre.z()}},
          {"up", o.up == UpAxis::kY ? "y" : "z"},
          {"height_m", o.height_m},
          {"world_from_input",
           "p_world = R_up * scale * (p_input - input_bbox_centre) + object_centre"},
          {"object_centre", {placed.centre.x(), placed.centre.y(), placed.centre.z()}},
          {"world_from_object", pose_to_json(world_from_object)}}},
        {"texture", o.texture.to_json()},
        {"noise", o.noise.to_json()},
        {"options", o.to_json()},
        {"seed", o.seed}};
    if (o.scene.any()) {  // absent without scene elements: scene.json as before
        scene_json["scene"] = placed.surroundings.to_json();
        scene_json["scene"]["options"] = o.scene.to_json();
    }
    io::write_text_atomic(gt / "scene.json", scene_json.dump(2) + "\n");
    io::write_mesh(gt / "mesh.ply", placed.mesh);
    summary.total_s = total.seconds();
}

}  // namespace

SynthSummary synthesize_capture(const Mesh& mesh, const fs::path& out_dir,
                                const SynthOptions& options, const Progress& progress) {
    options.check();
    SynthSummary summary;
    io::write_folder_atomic(out_dir, [&](const fs::path& folder) {
        write_capture(mesh, folder, options, progress, summary);
    });
    return summary;
}

}  // namespace rgbd::synth
