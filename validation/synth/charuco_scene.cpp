#include "validation/synth/charuco_scene.hpp"

#include <tbb/parallel_for.h>

#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>

#include "io/output_file.hpp"
#include "toolkit/error.hpp"
#include "toolkit/report.hpp"
#include "validation/synth/random.hpp"

namespace rgbd::synth {
namespace {

namespace fs = std::filesystem;
constexpr double kDeg = std::numbers::pi / 180.0;
enum SeedTag : std::uint64_t { kBoardSeed = 7, kDepthSeed = 8, kColorSeed = 9 };
constexpr std::uint8_t kInk = 25, kPaper = 225, kPlate = 230, kBack = 140;

/// Bilinear sample of a CV_8UC1 image at pixel coordinate (u, v) (centres at integers).
double sample(const cv::Mat& image, double u, double v) {
    u = std::clamp(u, 0.0, image.cols - 1.0);
    v = std::clamp(v, 0.0, image.rows - 1.0);
    const int c = std::min(static_cast<int>(u), image.cols - 2);
    const int r = std::min(static_cast<int>(v), image.rows - 2);
    const double a = u - c, b = v - r;
    const auto at = [&](int rr, int cc) {
        return static_cast<double>(image.at<std::uint8_t>(rr, cc));
    };
    return (1 - b) * ((1 - a) * at(r, c) + a * at(r, c + 1)) +
           b * ((1 - a) * at(r + 1, c) + a * at(r + 1, c + 1));
}

std::string frame_name(int index) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%06d.png", index);
    return buf;
}

}  // namespace

void BoardMotion::check() const {
    board.check();
    check_range("board margin", margin_m, Range::closed(0, 1), "m");
    check_range("board motion radius", radius_m, Range::closed(0, 10), "m");
    check_range("board facing jitter", facing_jitter_deg, Range::closed(0, 90), "deg");
    check_range("board roll", roll_deg, Range::closed(0, 180), "deg");
    check_range("board blur", blur_px, Range::closed(0, 50), "px");
    check_range("board texel", texture_mm, Range::closed(0.05, 5), "mm");
}

nlohmann::json BoardMotion::to_json() const {
    return {{"board", board.to_json()}, {"margin_m", margin_m},
            {"radius_m", radius_m},     {"facing_jitter_deg", facing_jitter_deg},
            {"roll_deg", roll_deg},     {"blur_px", blur_px},
            {"texture_mm", texture_mm}};
}

Pose board_pose(const BoardMotion& m, const SynthOptions& o, int set, const Eigen::Vector3d& centre,
                const std::vector<Eigen::Vector3d>& sensor_positions) {
    RGBD_CHECK(!sensor_positions.empty(), "board pose needs the sensors");
    const CounterRandom rng(derive_seed(o.seed, kBoardSeed));
    // Centre uniform in the ball.
    Eigen::Vector3d offset;
    for (std::uint64_t k = 0;; ++k) {  // rejection sampling: a few draws on average
        const std::uint64_t i = static_cast<std::uint64_t>(set) * 1024 + k;
        offset = Eigen::Vector3d(2 * rng.uniform(1, i) - 1, 2 * rng.uniform(2, i) - 1,
                                 2 * rng.uniform(3, i) - 1);
        if (offset.squaredNorm() <= 1.0 || k == 1023) break;
    }
    const Eigen::Vector3d c = centre + m.radius_m * offset;
    // Faces a random direction between two neighbouring sensors (so that both can see it),
    // jittered in azimuth and elevation.
    const int n = static_cast<int>(sensor_positions.size());
    const int k = std::min(n - 1, static_cast<int>(rng.uniform(4, set) * n));
    const Eigen::Vector3d d0 = (sensor_positions[k] - c).normalized();
    const Eigen::Vector3d d1 = (sensor_positions[(k + 1) % n] - c).normalized();
    const double t = rng.uniform(8, set);
    Eigen::Vector3d d = (d0 + t * (d1 - d0)).normalized();
    if (!d.allFinite() || d.norm() < 0.5) d = d0;
    const double az = (2 * rng.uniform(5, set) - 1) * m.facing_jitter_deg * kDeg;
    const double el = (2 * rng.uniform(6, set) - 1) * m.facing_jitter_deg * kDeg;
    d = Eigen::AngleAxisd(az, Eigen::Vector3d::UnitZ()) * d;
    const Eigen::Vector3d side = d.cross(Eigen::Vector3d::UnitZ()).normalized();
    d = Eigen::AngleAxisd(el, side) * d;
    // Board frame: z into the board (away from the viewers), x right and y down as they see it.
    Pose frame = look_at(c, c - d);
    const double roll = (2 * rng.uniform(7, set) - 1) * m.roll_deg * kDeg;
    frame.linear() =
        frame.linear() * Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    Pose centre_from_origin = Pose::Identity();
    centre_from_origin.translation() =
        Eigen::Vector3d(-0.5 * m.board.width_m(), -0.5 * m.board.height_m(), 0);
    return frame * centre_from_origin;
}

SynthSummary synthesize_charuco_capture(const fs::path& out_dir, const SynthOptions& options,
                                        const BoardMotion& motion, const Progress& progress) {
    options.check();
    motion.check();
    RGBD_CHECK(options.rig == RigKind::kRing, "a board capture needs the ring rig");
    const SyntheticRig rig = make_rig(options);
    const int nsensors = static_cast<int>(rig.sensors.size());
    std::vector<Eigen::Vector3d> positions;
    for (const auto& s : rig.sensors)
        positions.push_back(s.true_world_from_depth.front().translation());

    // Printed image, low-passed to about a colour pixel's footprint at 1 m so that point
    // sampling does not alias.
    const double ppm = 1000.0 / motion.texture_mm;
    cv::Mat printed = calibration::board_image(motion.board, ppm);
    printed.convertTo(printed, CV_8UC1, (kPaper - kInk) / 255.0, kInk);
    const double footprint_texels = 1.0 / rig.sensors[0].spec.color.fx * ppm;  // at 1 m
    if (footprint_texels > 1.0)
        cv::GaussianBlur(printed, printed, cv::Size(), 0.5 * footprint_texels);

    // The plate: the board plus the margin, two triangles in the board frame.
    const double w = motion.board.width_m(), h = motion.board.height_m(), mg = motion.margin_m;
    const std::vector<Eigen::Vector3d> plate = {
        {-mg, -mg, 0}, {w + mg, -mg, 0}, {w + mg, h + mg, 0}, {-mg, h + mg, 0}};
    SynthSummary summary;
    summary.sensors = nsensors;
    io::write_folder_atomic(out_dir, [&](const fs::path& root) {
        const Stopwatch total;
        io::Rig rig_json;
        for (const auto& s : rig.sensors) rig_json.sensors.push_back(s.spec);
        rig_json.extra["generator"] = "rgbd-synth";
        io::CaptureWriter writer(root, rig_json);
        const fs::path gt = root / "gt";
        for (const auto& s : rig.sensors) fs::create_directories(gt / s.spec.id / "depth_clean");
        nlohmann::json board_poses = nlohmann::json::object();
        for (int set = 0; set < options.frames; ++set) {
            const Pose world_from_board =
                board_pose(motion, options, set, rig.object_centre, positions);
            board_poses[std::to_string(set)] = pose_to_json(world_from_board);
            std::vector<Eigen::Vector3d> vertices;
            for (const auto& p : plate) vertices.push_back(world_from_board * p);
            const RenderScene scene(vertices, {{0, 1, 2}, {0, 2, 3}});
            const Pose board_from_world = world_from_board.inverse();
            std::vector<RenderedView> views(nsensors);
            const Stopwatch render;
            tbb::parallel_for(0, nsensors, [&](int i) {
                const auto& s = rig.sensors[i];
                const Pose& world_from_depth = s.true_world_from_depth[set];
                const std::uint64_t seed = derive_seed(options.seed, 200 + i, set);
                views[i].clean = render_depth(scene, s.spec.depth, world_from_depth);
                views[i].noisy = apply_depth_noise(views[i].clean, s.spec.depth, s.traits,
                                                   options.noise, derive_seed(seed, kDepthSeed));
                const Pose world_from_color = world_from_depth * s.spec.color_from_depth.inverse();
                // Printed side: the camera is on the board's -z side.
                const bool front = (board_from_world * world_from_color.translation()).z() < 0;
                views[i].color = render_color(
                    scene, s.spec.color, world_from_color,
                    [&](const Eigen::Vector3d& p_world, int) {
                        const std::uint8_t g = [&]() -> std::uint8_t {
                            if (!front) return kBack;
                            const Eigen::Vector3d b = board_from_world * p_world;
                            if (b.x() < 0 || b.y() < 0 || b.x() > w || b.y() > h) return kPlate;
                            return static_cast<std::uint8_t>(
                                std::lround(sample(printed, b.x() * ppm - 0.5, b.y() * ppm - 0.5)));
                        }();
                        return Rgb{g, g, g};
                    },
                    options.background);
                if (motion.blur_px > 0)
                    cv::GaussianBlur(views[i].color, views[i].color, cv::Size(), motion.blur_px);
                apply_color_noise(views[i].color, options.noise.color_sigma,
                                  derive_seed(seed, kColorSeed));
            });
            summary.render_s += render.seconds();
            io::FrameSet line;
            line.set = set;
            line.time_ns = rig.sensors[0].hub_time_ns[set];
            for (int i = 0; i < nsensors; ++i) {
                const auto& s = rig.sensors[i];
                writer.add_frame(s.spec.id, set, s.hub_time_ns[set] + s.spec.clock_offset_ns,
                                 views[i].noisy.depth, views[i].color);
                cv::Mat clean = views[i].clean.depth_float();
                clean.setTo(0, clean != clean);
                cv::Mat clean16;
                clean.convertTo(clean16, CV_16UC1, s.spec.depth_scale);
                io::write_image_atomic(gt / s.spec.id / "depth_clean" / frame_name(set), clean16);
                line.frames.push_back(set);
                const cv::Mat& d = views[i].noisy.depth;
                summary.valid_points.push_back(cv::countNonZero(d == d));
            }
            writer.add_frameset(line);
            summary.views += nsensors;
            ++summary.frames;
            if (!report_progress(progress, double(set + 1) / options.frames))
                throw AlgorithmError("cancelled");
        }
        nlohmann::json poses = nlohmann::json::object();
        for (const auto& s : rig.sensors)
            poses[s.spec.id] = pose_to_json(s.true_world_from_depth.front());
        io::write_text_atomic(gt / "world_from_depth.json", poses.dump(2) + "\n");
        io::write_text_atomic(gt / "board_poses.json", board_poses.dump(2) + "\n");
        io::write_text_atomic(gt / "board.json", motion.board.to_json().dump(2) + "\n");
        const nlohmann::json scene_json = {
            {"format", "rgbd-synth"},
            {"version", 1},
            {"units", "m"},
            {"target", "charuco"},
            {"ring_centre", {rig.object_centre.x(), rig.object_centre.y(), rig.object_centre.z()}},
            {"board_motion", motion.to_json()},
            {"noise", options.noise.to_json()},
            {"options", options.to_json()},
            {"seed", options.seed}};
        io::write_text_atomic(gt / "scene.json", scene_json.dump(2) + "\n");
        summary.total_s = total.seconds();
    });
    return summary;
}

}  // namespace rgbd::synth
