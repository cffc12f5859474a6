// rgbd-calibrate: the sensor network's extrinsics (rig.json) from a capture of a ChArUco board
// carried through the ring, or refined on whatever the sensors see (--refine).
// docs/algorithms.md §6b, issue 19. Board: algorithms/calibration/charuco_board.hpp; joint
// solve: algorithms/calibration/rig_solver.hpp; refinement: algorithms/calibration/
// rig_refinement.hpp and registration::align_views.
#include <malloc.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <mutex>

#include "algorithms/calibration/charuco_board.hpp"
#include "algorithms/calibration/rig_refinement.hpp"
#include "algorithms/calibration/rig_solver.hpp"
#include "algorithms/denoise/distance_outliers.hpp"
#include "algorithms/registration/icp.hpp"
#include "cli/common/stages.hpp"
#include "cli/common/tool.hpp"
#include "io/capture_folder.hpp"
#include "io/image_codec.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;
namespace fs = std::filesystem;

namespace {

calibration::BoardSpec read_board(const std::string& path) {
    std::ifstream in(path);
    RGBD_CHECK_AS(IoError, in.good(), path + ": cannot read the board file");
    try {
        return calibration::BoardSpec::from_json(nlohmann::json::parse(in));
    } catch (const nlohmann::json::exception& e) {
        throw InputError(path + ": not a JSON board description (" + std::string(e.what()) + ")");
    } catch (const InputError& e) {
        throw InputError(path + ": " + e.what());
    }
}

int sensor_index(const io::Rig& rig, const std::string& id) {
    for (std::size_t i = 0; i < rig.sensors.size(); ++i)
        if (rig.sensors[i].id == id) return static_cast<int>(i);
    throw cli::UsageError("--anchor: no sensor '" + id + "' in rig.json");
}

/// How far `after` moved points near `centre` from where `before` put them, and the rotation.
std::pair<double, double> change(const Pose& before, const Pose& after,
                                 const Eigen::Vector3d& centre) {
    const Pose motion = after * before.inverse();  // world -> world
    return {rotation_error_deg(before, after), (motion * centre - centre).norm()};
}

/// One colour image to search.
struct Job {
    int sensor = 0;
    std::int64_t set = 0;
    std::size_t position = 0;
};

/// The images of one frame that board detection needs: the colour image decoded as grey
/// (libjpeg then skips the chroma planes and the colour conversion: about half the decoding
/// time of BGR) and the depth in metres. Errors name the file.
struct BoardImages {
    cv::Mat grey;   ///< CV_8UC1, colour camera grid; empty when the frame has no colour
    cv::Mat depth;  ///< CV_32FC1 metres, NaN = invalid
};

BoardImages load_board_images(const io::Capture& capture, const io::SensorSpec& spec,
                              std::size_t position) {
    const io::FrameRecord& r = capture.frames.at(spec.id).at(position);
    auto resolve = [&](const std::string& p) {
        const fs::path path(p);
        return (path.is_absolute() ? path : capture.root / spec.id / path).string();
    };
    const std::string depth_file = resolve(r.depth);
    cv::Mat raw = io::read_image(depth_file);
    if (spec.depth_encoding != io::DepthEncoding::kPlain) {
        RGBD_CHECK(raw.type() == CV_16UC1, depth_file + ": depth image is not 16-bit");
        io::decode_depth(raw, spec.depth_encoding);
    }
    BoardImages out;
    out.depth = io::frame_from_stored(spec, raw, cv::Mat(), depth_file).depth;
    if (!r.color.empty()) {
        const std::string color_file = resolve(r.color);
        out.grey = io::read_image(color_file, io::ImageMode::kGrey);
        RGBD_CHECK(out.grey.cols == spec.color.width && out.grey.rows == spec.color.height,
                   color_file + ": colour image is " + std::to_string(out.grey.cols) + "x" +
                       std::to_string(out.grey.rows) + ", rig.json says " +
                       std::to_string(spec.color.width) + "x" + std::to_string(spec.color.height));
    }
    return out;
}

struct Found {
    Job job;
    calibration::DetectionOutcome outcome;
    calibration::PlaneCheck plane;
};

/// rgbd-calibrate CAPTURE -o rig.json: board detection, depth check, joint solve.
void calibrate_from_board(cli::Context& ctx, const io::Capture& capture, int anchor) {
    const calibration::BoardSpec board = ctx.options().count("board")
                                             ? read_board(ctx.get<std::string>("board"))
                                             : calibration::BoardSpec{};
    calibration::DetectionOptions detection;
    detection.min_corners = ctx.get<int>("min-corners");
    detection.max_rms_px = ctx.get<double>("max-rms-px");
    const double max_plane_mm = ctx.get<double>("max-plane-mm");
    try {
        detection.check();
        if (!(max_plane_mm > 0)) throw InputError("--max-plane-mm must be > 0");
    } catch (const InputError& e) {
        throw cli::UsageError(e.what());
    }
    const io::Rig& rig = capture.rig;
    const int n = static_cast<int>(rig.sensors.size());
    RGBD_CHECK(capture.framesets.size() > 0,
               capture.root.string() + ": no framesets.csv (a board capture needs frame sets)");

    std::vector<Job> jobs;
    for (const auto& set : capture.framesets)
        for (int s = 0; s < n && s < static_cast<int>(set.frames.size()); ++s) {
            if (set.frames[s] < 0) continue;
            const auto position = capture.find_frame(rig.sensors[s].id, set.frames[s]);
            if (position) jobs.push_back({s, set.set, *position});
        }
    RGBD_CHECK(!jobs.empty(), capture.root.string() + ": the frame sets name no frames");
    // Every image allocates a few buffers of 2-6 MB (decoding, thresholds, contours). glibc
    // maps blocks that large with mmap and unmaps them on free, so each image paid its pages'
    // faults again: 30% of the CPU time of 8 sensors x 40 frame sets went to the kernel. Keep
    // them in the heap instead (the two threads' buffers are reused image after image).
    mallopt(M_MMAP_THRESHOLD, 64 << 20);
    mallopt(M_TRIM_THRESHOLD, 256 << 20);
    std::vector<Found> found(jobs.size());
    auto bar = ctx.progress("detect");
    std::mutex mutex;
    std::size_t done = 0;
    tbb::parallel_for(std::size_t{0}, jobs.size(), [&](std::size_t i) {
        const Job& job = jobs[i];
        const auto& spec = rig.sensors[job.sensor];
        const BoardImages frame = load_board_images(capture, spec, job.position);
        found[i].job = job;
        if (!frame.grey.empty())
            found[i].outcome = calibration::detect_board(frame.grey, spec.color, board, detection);
        if (found[i].outcome.observation && !frame.depth.empty()) {
            const Pose depth_from_board =
                spec.color_from_depth.inverse() * found[i].outcome.observation->camera_from_board;
            found[i].plane =
                calibration::check_board_plane(frame.depth, spec.depth, board, depth_from_board);
        }
        const std::lock_guard lock(mutex);
        bar.update(static_cast<double>(++done) / jobs.size());
    });

    // Observations, after the depth check of the board plane.
    std::vector<calibration::Observation> observations;
    std::vector<std::vector<double>> plane_mm(n);
    int with_markers = 0, checked = 0, off_plane = 0;
    std::vector<double> all_plane;
    for (const Found& f : found) {
        if (f.outcome.markers > 0) ++with_markers;
        if (!f.outcome.observation) {
            if (!f.outcome.rejected.empty())
                ctx.info(rig.sensors[f.job.sensor].id + " frame set " + std::to_string(f.job.set) +
                         ": board rejected: " + f.outcome.rejected);
            continue;
        }
        if (f.plane.pixels >= 50) {
            ++checked;
            all_plane.push_back(f.plane.median_mm);
            if (std::abs(f.plane.median_mm) > max_plane_mm) {
                ++off_plane;
                ctx.info(rig.sensors[f.job.sensor].id + " frame set " + std::to_string(f.job.set) +
                         ": board plane " + cli::formatted("%.1f", f.plane.median_mm) +
                         " mm off the depth: left out");
                continue;
            }
            plane_mm[f.job.sensor].push_back(f.plane.median_mm);
        }
        observations.push_back({f.job.sensor, static_cast<int>(f.job.set), *f.outcome.observation});
    }
    const std::string where = capture.root.string();
    if (observations.empty() && off_plane == 0) {
        if (with_markers == 0)
            throw InputError(where + ": no board visible: no " + board.dictionary +
                             " marker of the board in any of " + std::to_string(jobs.size()) +
                             " colour images");
        throw InputError(where + ": board markers in " + std::to_string(with_markers) +
                         " images but no usable board (too few corners, blurred, or not the "
                         "board of --board)");
    }
    if (checked >= 3 && 2 * off_plane > checked) {
        std::nth_element(all_plane.begin(), all_plane.begin() + all_plane.size() / 2,
                         all_plane.end());
        throw InputError(where + ": the board does not match the printed one: in " +
                         std::to_string(off_plane) + " of " + std::to_string(checked) +
                         " views the board plane from the colour image lies " +
                         cli::formatted("%.0f", all_plane[all_plane.size() / 2]) +
                         " mm (median) from the depth; check square_m and marker_m of --board");
    }

    calibration::RigSolveOptions solve;
    solve.anchor = anchor;
    std::vector<PinholeIntrinsics> intrinsics;
    for (const auto& s : rig.sensors) intrinsics.push_back(s.color);
    const auto lost = calibration::unconnected_cameras(n, observations, anchor);
    if (!lost.empty()) {
        std::string names;
        for (int c : lost) {
            int seen = 0;
            for (const auto& o : observations) seen += o.sensor == c;
            names += (names.empty() ? "" : ", ") + rig.sensors[c].id + " (board in " +
                     std::to_string(seen) + " frame sets)";
        }
        throw InputError(where + ": cannot connect " + names + " to the anchor " +
                         rig.sensors[anchor].id +
                         ": no frame set in which they see the board together with a connected "
                         "sensor");
    }
    const calibration::RigSolution solution =
        calibration::solve_rig(intrinsics, observations, board, solve);

    // The anchor keeps its rig.json pose; every other sensor follows the solve.
    io::Rig out = rig;
    const auto& a = rig.sensors[anchor];
    const Pose world_from_anchor_color = a.world_from_depth * a.color_from_depth.inverse();
    const Eigen::Vector3d centre = cli::object_centre(rig).value_or(Eigen::Vector3d::Zero());
    Report sensors = Report::array();
    std::cout << "sensor        obs  linked  reproj_rms_px  plane_median_mm  plane_rms_mm  "
                 "change_deg  change_mm\n";
    for (int s = 0; s < n; ++s) {
        auto& spec = out.sensors[s];
        const auto& cam = solution.cameras[s];
        spec.world_from_depth =
            world_from_anchor_color * cam.anchor_from_camera * spec.color_from_depth;
        spec.has_world_from_depth = true;
        std::vector<double> planes = plane_mm[s];
        double med = 0, rms = 0;
        if (!planes.empty()) {
            std::nth_element(planes.begin(), planes.begin() + planes.size() / 2, planes.end());
            med = planes[planes.size() / 2];
            for (double v : plane_mm[s]) rms += v * v;
            rms = std::sqrt(rms / plane_mm[s].size());
        }
        const auto [deg, m] =
            change(rig.sensors[s].world_from_depth, spec.world_from_depth, centre);
        std::printf("%-12s %4d  %6d  %13.3f  %15.2f  %12.2f  %10.3f  %9.1f\n", spec.id.c_str(),
                    cam.observations, cam.linked, cam.rms_px, med, rms, deg, 1e3 * m);
        sensors.push_back({{"id", spec.id},
                           {"observations", cam.observations},
                           {"linked", cam.linked},
                           {"reprojection_rms_px", cam.rms_px},
                           {"plane_median_mm", med},
                           {"plane_rms_mm", rms},
                           {"change_deg", deg},
                           {"change_mm", 1e3 * m}});
    }
    std::cout << std::flush;
    ctx.note(std::to_string(observations.size()) + " board views, " +
             std::to_string(solution.boards) + " board poses, " +
             std::to_string(solution.residuals) + " corners: reprojection RMS " +
             cli::formatted("%.3f px (start %.3f px) after %d iterations", solution.final_rms_px,
                            solution.initial_rms_px, solution.iterations));
    io::write_rig(ctx.output_path(), out);
    ctx.metrics()["mode"] = "board";
    ctx.metrics()["board"] = board.to_json();
    ctx.metrics()["sensors"] = sensors;
    ctx.metrics()["reprojection_rms_px"] = solution.final_rms_px;
    ctx.metrics()["initial_rms_px"] = solution.initial_rms_px;
    ctx.metrics()["board_views"] = observations.size();
    ctx.metrics()["board_poses"] = solution.boards;
    ctx.metrics()["left_out_off_plane"] = off_plane;
}

/// Depth images of `sensor` (index s) in up to `count` frame sets from `first` on (the frames
/// those sets name; sets that miss the sensor are skipped), as positions in its frame list.
std::vector<std::size_t> sensor_positions(const io::Capture& capture, std::size_t s,
                                          std::size_t first_position, long long first, int count) {
    std::vector<std::size_t> out{first_position};
    const std::string& id = capture.rig.sensors[s].id;
    for (long long k = first + 1; k < static_cast<long long>(capture.framesets.size()) &&
                                  static_cast<int>(out.size()) < count;
         ++k) {
        const io::FrameSet& set = capture.framesets[k];
        if (s >= set.frames.size() || set.frames[s] < 0) continue;
        if (const auto position = capture.find_frame(id, set.frames[s])) out.push_back(*position);
    }
    return out;
}

/// rgbd-calibrate CAPTURE --refine -o rig.json: multi-view registration of the sensors' views,
/// each the per-pixel mean of the agreeing depths of up to --sets frame sets (docs/algorithms.md
/// §6b).
void refine_on_object(cli::Context& ctx, const io::Capture& capture, int anchor) {
    const io::Rig& rig = capture.rig;
    for (const auto& s : rig.sensors)
        RGBD_CHECK(s.has_world_from_depth,
                   capture.root.string() + "/rig.json: sensor " + s.id +
                       " has no world_from_depth (--refine starts from the rig's poses)");
    RGBD_CHECK(rig.sensors.size() >= 2, capture.root.string() + ": --refine needs 2+ sensors");
    const int sets = ctx.get<int>("sets");
    if (sets < 1 || sets > 1000) throw cli::UsageError("--sets must be in [1, 1000]");
    const long long frameset = ctx.get<long long>("frameset");
    const auto jobs = cli::select_frames(capture, frameset, std::string(), {}, &ctx);
    const auto centre = cli::object_centre(capture, jobs);
    frames::CloudOptions cloud_options;
    cli::ExtractionOptions extraction;
    denoise::DistanceOptions distance;
    std::vector<PointCloud> views;
    std::vector<int> view_sensor;
    int fixed = -1;
    std::size_t most_sets = 0;
    for (const auto& [id, position] : jobs) {
        Report report;
        const int s = sensor_index(rig, id);
        const std::vector<std::size_t> positions =
            capture.framesets.empty()
                ? std::vector<std::size_t>{position}
                : sensor_positions(capture, static_cast<std::size_t>(s), position, frameset, sets);
        most_sets = std::max(most_sets, positions.size());
        RgbdFrame frame = io::load_frame(capture, id, position);
        if (positions.size() > 1) {
            std::vector<cv::Mat> depths{frame.depth};
            for (std::size_t k = 1; k < positions.size(); ++k)
                depths.push_back(io::load_frame(capture, id, positions[k]).depth);
            frame.depth = calibration::combined_depth(depths);
        }
        PointCloud view = cli::view_from_frame(frame, static_cast<int>(views.size()), cloud_options,
                                               centre, extraction, report);
        denoise::remove_distance_outliers(view, distance);
        if (view.empty()) {
            ctx.warn(id + ": no points on the object; its pose is kept");
            continue;
        }
        if (s == anchor) fixed = static_cast<int>(views.size());
        view_sensor.push_back(s);
        views.push_back(std::move(view));
    }
    RGBD_CHECK_AS(AlgorithmError, fixed >= 0,
                  "the anchor " + rig.sensors[anchor].id + " sees nothing in this frame set");
    RGBD_CHECK_AS(AlgorithmError, views.size() >= 2, "fewer than 2 sensors see the object");
    ctx.note("depth: per-pixel mean of " + std::to_string(most_sets) + " frame set" +
             (most_sets == 1 ? "" : "s") + " (the depths near their median) from frame set " +
             std::to_string(frameset));
    cli::colour_hidden_points(views);  // view_from_frame left them grey
    const registration::MultiViewOptions options =
        calibration::rig_refinement_options(static_cast<std::size_t>(fixed), ctx.seed());
    auto bar = ctx.progress("refine");
    const auto result = registration::align_views(views, options, bar.callback());
    io::Rig out = rig;
    const Eigen::Vector3d c = centre.value_or(Eigen::Vector3d::Zero());
    Report sensors = Report::array();
    std::string failed;
    std::cout << "sensor        verdict  fitness  rmse_mm  change_deg  change_mm\n";
    for (std::size_t v = 0; v < views.size(); ++v) {
        const auto& r = result.views[v];
        auto& spec = out.sensors[view_sensor[v]];
        const Pose before = spec.world_from_depth;
        spec.world_from_depth = orthonormalized(r.world_from_sensor);
        const auto [deg, m] = change(before, spec.world_from_depth, c);
        std::printf("%-12s %-7s  %7.3f  %7.2f  %10.3f  %9.1f\n", spec.id.c_str(),
                    registration::to_string(r.verdict), r.fitness, 1e3 * r.inlier_rmse, deg,
                    1e3 * m);
        if (r.verdict != registration::Verdict::kPass)
            failed += (failed.empty() ? "" : ", ") + spec.id + " (" + r.reason + ")";
        sensors.push_back({{"id", spec.id},
                           {"verdict", registration::to_string(r.verdict)},
                           {"fitness", r.fitness},
                           {"inlier_rmse_mm", 1e3 * r.inlier_rmse},
                           {"change_deg", deg},
                           {"change_mm", 1e3 * m}});
    }
    std::cout << std::flush;
    if (!failed.empty())
        throw AlgorithmError("refinement not trusted for " + failed + "; rig.json not written");
    io::write_rig(ctx.output_path(), out);
    ctx.metrics()["mode"] = "refine";
    ctx.metrics()["framesets_combined"] = most_sets;
    ctx.metrics()["sensors"] = sensors;
    ctx.metrics()["alignment"] = result.to_json();
}

}  // namespace

int main(int argc, char** argv) {
    cli::ToolSpec spec;
    spec.name = "rgbd-calibrate";
    spec.usage =
        "rgbd-calibrate CAPTURE -o rig.json [--board FILE.json] [--anchor ID]\n"
        "       rgbd-calibrate CAPTURE --refine -o rig.json [--frameset N] [--sets N]";
    spec.description =
        "Calibrates the extrinsics of a sensor network and writes rig.json (every other field\n"
        "kept from the capture's rig.json; the anchor sensor keeps its pose).\n"
        "From a board capture: detects the ChArUco board (OpenCV aruco) in every colour image\n"
        "with the colour intrinsics of rig.json, estimates its pose per image, checks the board\n"
        "plane against the depth image (views off by more than --max-plane-mm are left out; when\n"
        "most are, the board file does not match the printed board: exit 1), links sensors that\n"
        "see the board in the same frame set and solves all poses jointly (bundle adjustment of\n"
        "the corner reprojection errors over all observations, the anchor fixed), so no error\n"
        "piles up around the ring. Prints per sensor the board views, those shared with another\n"
        "sensor, the reprojection RMS (px), the board-plane depth residual (median and RMS, mm)\n"
        "and the change from the capture's rig.json at the ring centre. Fails (exit 1, no\n"
        "output) when no board is visible or naming the sensors it cannot connect.\n"
        "With --refine: starts from the capture's rig.json and refines the poses on whatever\n"
        "the sensors see (a person standing still, a bust) with the toolkit's multi-view\n"
        "registration (rgbd-align's align_views, joint rounds from the rig's poses); each\n"
        "sensor's depth is the per-pixel mean of --sets frame sets' depths near their median\n"
        "(one frame's noise leaves ~0.3 deg on a rounded object). Prints the change per sensor\n"
        "and writes nothing (exit 1)\n"
        "unless every sensor's alignment verdict is PASS.\n"
        "Board file: {\"squares_x\": 7, \"squares_y\": 5, \"square_m\": 0.08, \"marker_m\": 0.06,\n"
        "\"dictionary\": \"DICT_5X5_100\"} (these are the defaults).";
    spec.example =
        "rgbd-synth --target charuco -o board --calib-error-deg 10 --calib-error-mm 100\n"
        "  rgbd-calibrate board -o rig.json && cp rig.json capture/rig.json\n"
        "  rgbd-calibrate capture --refine -o rig_refined.json";
    spec.writes_stream = false;
    spec.writes_file = true;
    spec.reads_stream = false;
    spec.add_options = [](cli::po::options_description& o) {
        o.add_options()("board", cli::po::value<std::string>()->value_name("FILE.json"),
                        "the printed board (default 7x5 squares of 0.08 m, markers 0.06 m, "
                        "DICT_5X5_100)")(
            "anchor", cli::po::value<std::string>()->value_name("ID"),
            "sensor whose pose is fixed (default: the first in rig.json)")(
            "refine", "refine the capture's rig.json on the object instead of a board")(
            "frameset", cli::value<long long>(0, "N"), "--refine: the first frame set to register")(
            "sets", cli::value<int>(8, "N"),
            "--refine: frame sets (from --frameset on) whose depth is combined by a per-pixel "
            "mean around the median; the scene must stand still (pixels that change are left out)")(
            "min-corners", cli::value<int>(calibration::DetectionOptions{}.min_corners, "N"),
            "board views with fewer corners are not used")(
            "max-rms-px", cli::value<double>(calibration::DetectionOptions{}.max_rms_px, "PX"),
            "board views whose pose reprojects worse are not used")(
            "max-plane-mm", cli::value<double>(20.0, "MM"),
            "board views whose plane lies farther from the depth are left out");
    };
    return cli::run_tool(argc, argv, spec, [&](cli::Context& ctx) {
        if (ctx.inputs().size() != 1) throw cli::UsageError("expected exactly one capture folder");
        if (ctx.output_path().empty()) throw cli::UsageError("missing -o rig.json");
        const bool refine = ctx.options().count("refine") > 0;
        if (refine && ctx.options().count("board"))
            throw cli::UsageError("--board is for board captures, not --refine");
        const io::Capture capture = io::open_capture(ctx.inputs().front());
        const int anchor = ctx.options().count("anchor")
                               ? sensor_index(capture.rig, ctx.get<std::string>("anchor"))
                               : 0;
        if (refine)
            refine_on_object(ctx, capture, anchor);
        else
            calibrate_from_board(ctx, capture, anchor);
    });
}
