// rgbd-synth: renders a synthetic RGB-D capture of a mesh (capture folder v1 plus gt/) from a
// virtual ring of Kinect v2 sensors or an SR300-like sensor and a turntable, with sensor
// noise, calibration error and clock offsets (docs/formats.md; docs/algorithms.md, synthetic ground
// truth). Validation tool: it does not use cli/common (docs/architecture.md), but follows its
// conventions (cli/README.md). See also: validation/synth/synthesize.hpp.
#include <unistd.h>

#include <boost/program_options.hpp>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "io/mesh_io.hpp"
#include "toolkit/error.hpp"
#include "toolkit/option_names.hpp"
#include "toolkit/report.hpp"
#include "validation/synth/charuco_scene.hpp"
#include "validation/synth/synthesize.hpp"

namespace po = boost::program_options;
namespace fs = std::filesystem;

namespace {

constexpr const char* kTool = "rgbd-synth";
#ifndef RGBD_VERSION
#define RGBD_VERSION "0.0.0"
#endif

struct UsageError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

/// The checks cli/common's driver makes for the tools (validation/ stays off cli/): a value as
/// typed must not be negative for an unsigned option (Boost wraps --seed -1 to 2^64 - 1) nor a
/// non-finite number; an option of a mode not chosen is an error, not ignored.
void check_given(const po::parsed_options& parsed, const po::variables_map& vm,
                 const std::string& rig, const std::string& target, const std::string& motion) {
    for (const auto& o : parsed.options) {
        if (o.string_key.empty() || !vm.count(o.string_key) || o.value.empty()) continue;
        const boost::any& v = vm[o.string_key].value();
        if (v.type() == typeid(std::uint64_t) && o.value.front().find('-') != std::string::npos)
            throw UsageError("--" + o.string_key + " must be >= 0, got " + o.value.front());
        if (const auto* d = boost::any_cast<double>(&v); d && !std::isfinite(*d))
            throw UsageError("--" + o.string_key + " must be a finite number, got " +
                             o.value.front());
    }
    const auto given = [&](const char* name) { return vm.count(name) && !vm[name].defaulted(); };
    const auto only = [&](bool applies, std::initializer_list<const char*> names,
                          const std::string& mode) {
        for (const char* name : names)
            if (!applies && given(name))
                throw UsageError(std::string("--") + name + " applies only with " + mode);
    };
    only(rig == "turntable", {"axis-tilt-deg", "axis-shift-mm", "angle-noise-deg", "stand"},
         "--rig turntable");
    only(target == "charuco", {"board", "board-radius-m", "board-blur-px"}, "--target charuco");
    only(motion != "none", {"motion-deg"}, "--motion turn or nod");
    only(motion == "nod", {"motion-period-s"}, "--motion nod");
}

void print_help(const po::options_description& options) {
    std::cout
        << "Usage: rgbd-synth MESH -o CAPTURE_DIR [options]\n"
           "       rgbd-synth --target charuco -o CAPTURE_DIR [--board FILE.json] [options]\n\n"
           "Renders a synthetic RGB-D capture of MESH (.off, .obj or .ply) with ground truth:\n"
           "a ring of Kinect v2 sensors (512x424 depth, 1920x1080 colour, 52 mm apart) looking\n"
           "at the object, or one SR300-like sensor in front of a turntable with 12 stops of\n"
           "30 degrees (--stops N), whose true axis is tilted and shifted from the nominal one\n"
           "that frames.csv's poses assume (--axis-tilt-deg, --axis-shift-mm). Depth is rasterised "
           "exactly, colour comes from a procedural solid\n"
           "texture seen by the colour camera itself. Noise (default): Kinect v2 axial\n"
           "sigma_z(z, theta), 0.8 px edge jitter, 50% flying pixels at discontinuities,\n"
           "grazing dropouts 70-85 deg, 0.5% dropouts, 0.5% outliers, 1 mm quantisation,\n"
           "colour noise 2 grey levels and JPEG. rig.json poses carry a calibration error\n"
           "(sensor 0 exact); frame times are in each sensor's clock (random offsets).\n"
           "Writes CAPTURE_DIR/{rig.json, framesets.csv, <sensor>/, gt/} where gt/ holds the\n"
           "true poses, the placed mesh (gt/mesh.ply), clean depth, per-pixel labels, clock\n"
           "offsets and scene parameters. CAPTURE_DIR must not exist or be empty; it appears\n"
           "only when complete.\n\n"
           "--target charuco renders a calibration capture instead (no MESH): a ChArUco board\n"
           "(default 7 x 5 squares of 80 mm, 60 mm markers, DICT_5X5_100; --board FILE.json\n"
           "with squares_x, squares_y, square_m, marker_m, dictionary) printed on one side of a\n"
           "plate and carried through the ring in random poses (centre within --board-radius-m\n"
           "of the ring centre, facing between two neighbouring sensors), one pose per frame set "
           "(--frames,\n"
           "default 40), seen by the sensors in front of it. gt/ holds world_from_depth.json,\n"
           "board_poses.json (world_from_board per frame set) and board.json.\n\n"
           "Scene around the object (ring rig, static object; --rig turntable and --motion\n"
           "refuse them): --floor under the object's lowest point (8 m square, grey tiles),\n"
           "--plinth-height-m H (a box under the object, 1.2 x its footprint; the floor then\n"
           "lies H lower), --walls N (2.5 m tall, 1 m beyond the ring, at 0, 90, 180, 270 deg),\n"
           "--clutter N (boxes and cylinders of 0.1-0.5 m on the floor level at 0.6-1.3 x the\n"
           "ring radius, 0.3 m or more from the object), --people N (0.45 x 0.3 x 1.7 m boxes\n"
           "at 1.2-1.6 x the ring radius); --scene room = --floor --walls 2 --clutter 4\n"
           "--people 1 (explicit options override it). Placement follows --seed; no element\n"
           "encloses a sensor. gt/mesh.ply stays the object alone; gt/<sensor>/segment/ labels\n"
           "every depth pixel (0 no return, 1 object, 2 floor/plinth/platter, 3 walls/clutter/\n"
           "people, 4 valid depth without a surface) and gt/scene.json's \"scene\" entry holds\n"
           "the floor height and every element's geometry.\n\n"
        << options
        << "\nExample:\n"
           "  rgbd-synth /tmp/cgaldata/data/meshes/bunny00.off -o cap --up y --height-m 0.45\n"
           "  rgbd-cloud cap --frameset 0 | rgbd-clean --distance | rgbd-align ...\n"
           "  rgbd-synth bunny00.off -o room --up y --scene room --resolution-scale 0.5\n"
           "  rgbd-synth max-planck.obj -o tt --rig turntable --stops 24 --height-m 0.25\n"
           "  rgbd-synth --target charuco -o board --calib-error-deg 10 --calib-error-mm 100\n"
           "  rgbd-calibrate board -o rig.json\n";
}

}  // namespace

int main(int argc, char** argv) {
    rgbd::synth::SynthOptions options;
    std::string mesh_path, out_dir, rig = "ring", up = "y", noise = "default", target = "object";
    std::string board_path;
    rgbd::synth::BoardMotion motion;
    int verbosity = 0, stops = 12;
    std::string scene_name = "bare";
    rgbd::synth::SceneOptions scene;
    std::string motion_kind = "none";
    double fps = 30.0;
    bool quiet = false;
    po::options_description visible("Options");
    // clang-format off
    visible.add_options()
        ("help,h", "print this help and exit")
        ("version", "print the version and exit")
        ("output,o", po::value(&out_dir)->value_name("DIR"), "capture folder to create (required)")
        ("rig", po::value(&rig)->default_value("ring")->value_name("ring|turntable"),
         "virtual rig")
        ("sensors", po::value(&options.sensors)->default_value(8)->value_name("N"),
         "ring: number of sensors, 360/N degrees apart, on a 1.5 m ring at 1.6 m tilted 10 deg")
        ("height-m", po::value(&options.height_m)->default_value(0.45, "0.45")->value_name("H"),
         "object height after scaling, metres")
        ("up", po::value(&up)->default_value("y")->value_name("y|z"), "up axis of the mesh")
        ("noise", po::value(&noise)->default_value("default")->value_name("default|none"),
         "sensor noise model")
        ("calib-error-deg", po::value(&options.calib_error_deg)->default_value(1.5)
             ->value_name("D"), "rotation error of every rig.json pose but sensor 0, degrees")
        ("calib-error-mm", po::value(&options.calib_error_mm)->default_value(15.0, "15")
             ->value_name("M"), "translation error of every rig.json pose but sensor 0, mm")
        ("stops", po::value(&stops)->value_name("N"),
         "turntable: number of stops, 360/N degrees apart (default 12)")
        ("axis-tilt-deg", po::value(&options.axis_tilt_deg)->default_value(1.5)->value_name("D"),
         "turntable truth: tilt of the true rotation axis from the nominal one, degrees")
        ("axis-shift-mm", po::value(&options.axis_shift_mm)->default_value(15.0, "15")
             ->value_name("M"), "turntable truth: horizontal offset of the true axis, mm")
        ("angle-noise-deg", po::value(&options.angle_noise_deg)->default_value(0.2, "0.2")
             ->value_name("D"), "turntable truth: std of each stop's angle error, degrees")
        ("stand", po::bool_switch(&options.stand),
         "turntable: render the platter the object stands on (dark disc, not in gt/mesh.ply)")
        ("scene", po::value(&scene_name)->default_value("bare")->value_name("bare|room"),
         "ring: elements around the object; room = --floor --walls 2 --clutter 4 --people 1")
        ("floor", po::bool_switch(&scene.floor), "ring: a floor at the object's lowest point "
         "(minus --plinth-height-m)")
        ("plinth-height-m", po::value(&scene.plinth_height_m)->default_value(0.0, "0")
             ->value_name("H"), "ring: a box plinth of height H under the object (0 = none)")
        ("walls", po::value(&scene.walls)->default_value(0)->value_name("N"),
         "ring: N walls (0-4) 1 m beyond the ring, 90 degrees apart")
        ("clutter", po::value(&scene.clutter)->default_value(0)->value_name("N"),
         "ring: N boxes and cylinders on the floor level around the object")
        ("people", po::value(&scene.people)->default_value(0)->value_name("N"),
         "ring: N standing people (boxes) outside the ring")
        ("resolution-scale", po::value(&options.resolution_scale)->default_value(1.0, "1")
             ->value_name("F"), "multiply the depth and colour pixel counts per side by F "
         "(0.1-4; e.g. 0.5 for fast tests)")
        ("frames", po::value(&options.frames)->default_value(1)->value_name("N"),
         "frame sets (turntable: frames per stop); static scene, fresh noise each, unless "
         "--motion")
        ("motion", po::value(&motion_kind)->default_value("none")->value_name("none|turn|nod"),
         "ring: the object moves rigidly over the frame sets (3D video tests): turn about the "
         "vertical axis, or nod about a horizontal one; truth in gt/motion.json")
        ("motion-deg", po::value(&options.motion_deg)->default_value(90.0, "90")->value_name("D"),
         "turn: degrees per second; nod: amplitude in degrees")
        ("motion-period-s", po::value(&options.motion_period_s)->default_value(2.0, "2")
             ->value_name("S"), "nod: period in seconds")
        ("fps", po::value(&fps)->default_value(30.0, "30")->value_name("F"),
         "frame sets per second (times in frames.csv, the motion's clock)")
        ("seed", po::value(&options.seed)->default_value(1)->value_name("S"),
         "random seed (noise, calibration error, clock offsets, turntable truth)")
        ("target", po::value(&target)->default_value("object")->value_name("object|charuco"),
         "what the ring sees: MESH, or a moving ChArUco board (calibration capture)")
        ("board", po::value(&board_path)->value_name("FILE.json"),
         "charuco: the board (default 7x5 squares, 0.08 m, markers 0.06 m, DICT_5X5_100)")
        ("board-radius-m", po::value(&motion.radius_m)->default_value(0.3, "0.3")
             ->value_name("R"), "charuco: board centres within R m of the ring centre")
        ("board-blur-px", po::value(&motion.blur_px)->default_value(0.0, "0")->value_name("S"),
         "charuco: Gaussian blur of the colour images, sigma in pixels (motion blur, focus)")
        ("quiet,q", po::bool_switch(&quiet), "no summary line")
        ("verbose,v", po::value<std::vector<std::string>>()->zero_tokens()->composing(),
         "more messages on stderr (repeatable)");
    // clang-format on
    po::options_description hidden;
    hidden.add_options()("mesh", po::value(&mesh_path));
    po::options_description all;
    all.add(visible).add(hidden);
    po::positional_options_description positional;
    positional.add("mesh", 1);

    // The options given with a value, as typed: a refused value's message names its option.
    std::vector<rgbd::GivenOption> given;
    try {
        po::variables_map vm;
        try {
            po::parsed_options parsed =
                po::command_line_parser(argc, argv).options(all).positional(positional).run();
            for (const auto& opt : parsed.options) {
                if (opt.string_key == "verbose") ++verbosity;
                if (opt.string_key != "mesh" && !opt.value.empty())
                    given.push_back({opt.string_key, opt.value.front()});
            }
            po::store(parsed, vm);
            po::notify(vm);
            if (!vm.count("help") && !vm.count("version"))
                check_given(parsed, vm, rig, target, motion_kind);
        } catch (const po::error& e) {
            throw UsageError(e.what());
        }
        if (vm.count("help")) {
            print_help(visible);
            return 0;
        }
        if (vm.count("version")) {
            std::cout << kTool << " " << RGBD_VERSION << "\n";
            return 0;
        }
        const bool charuco = target == "charuco";
        if (!charuco && target != "object")
            throw UsageError("unknown target '" + target + "' (expected object or charuco)");
        if (!charuco && mesh_path.empty()) throw UsageError("missing MESH argument");
        if (charuco && !mesh_path.empty()) throw UsageError("--target charuco takes no MESH");
        if (out_dir.empty()) throw UsageError("missing -o CAPTURE_DIR");
        try {
            options.rig = rgbd::synth::parse_rig_kind(rig);
            options.up = rgbd::synth::parse_up_axis(up);
            options.motion = rgbd::synth::parse_motion_kind(motion_kind);
            // --scene sets the defaults; options given explicitly override it.
            options.scene = rgbd::synth::scene_preset(scene_name);
            options.scene.floor = options.scene.floor || scene.floor;
            if (!vm["plinth-height-m"].defaulted())
                options.scene.plinth_height_m = scene.plinth_height_m;
            if (!vm["walls"].defaulted()) options.scene.walls = scene.walls;
            if (!vm["clutter"].defaulted()) options.scene.clutter = scene.clutter;
            if (!vm["people"].defaulted()) options.scene.people = scene.people;
            rgbd::check_range("--fps", fps, rgbd::Range::open_closed(0, 1000));
            options.frame_period_s = 1.0 / fps;
            if (noise == "none")
                options.noise = rgbd::synth::NoiseOptions::none();
            else if (noise != "default")
                throw rgbd::InputError("unknown noise '" + noise + "' (expected default or none)");
            options.mesh_source = fs::path(mesh_path).filename().string();
            if (charuco) {
                if (vm["frames"].defaulted()) options.frames = 40;
                if (options.rig != rgbd::synth::RigKind::kRing)
                    throw rgbd::InputError("--target charuco needs --rig ring");
                if (options.scene.any())
                    throw rgbd::InputError("--target charuco takes no scene elements");
                motion.check();
            }
            if (vm.count("stops")) {
                if (options.rig != rgbd::synth::RigKind::kTurntable)
                    throw rgbd::InputError("--stops needs --rig turntable");
                rgbd::check_range("--stops", stops, rgbd::Range::closed(1, 3600));
                options.turntable_stops = stops;
                options.turntable_step_deg = 360.0 / stops;
            }
            options.check();
        } catch (const rgbd::InputError& e) {
            throw UsageError(e.what());
        }
        if (charuco && !board_path.empty()) {
            std::ifstream in(board_path);
            if (!in) throw rgbd::IoError("cannot read board file " + board_path);
            try {
                motion.board = rgbd::calibration::BoardSpec::from_json(nlohmann::json::parse(in));
            } catch (const std::exception& e) {
                throw rgbd::InputError(board_path + ": " + e.what());
            }
        }
        if (fs::exists(out_dir) && !(fs::is_directory(out_dir) && fs::is_empty(out_dir)))
            throw rgbd::IoError("output folder exists and is not empty: " + out_dir);

        const rgbd::Stopwatch watch;
        const rgbd::Mesh mesh = charuco ? rgbd::Mesh() : rgbd::io::read_mesh(mesh_path);
        if (verbosity > 0 && !charuco)
            std::cerr << kTool << ": read " << mesh_path << ": " << mesh.number_of_vertices()
                      << " vertices, " << mesh.number_of_faces() << " faces\n";
        rgbd::Progress progress;
        if (!quiet && ::isatty(STDERR_FILENO)) {
            progress = [](double f) {
                std::fprintf(stderr, "\r%s: rendering %3d%%", kTool, static_cast<int>(100 * f));
                std::fflush(stderr);
                return true;
            };
        }
        const auto summary =
            charuco ? rgbd::synth::synthesize_charuco_capture(out_dir, options, motion, progress)
                    : rgbd::synth::synthesize_capture(mesh, out_dir, options, progress);
        if (progress) std::fprintf(stderr, "\n");
        if (verbosity > 0) {
            std::ostringstream counts;
            for (std::size_t i = 0; i < summary.valid_points.size(); ++i)
                counts << (i ? " " : "") << summary.valid_points[i];
            std::cerr << kTool << ": valid depth pixels per view: " << counts.str() << "\n"
                      << kTool << ": render " << summary.render_s << " s\n";
        }
        if (!quiet) {
            std::fprintf(stderr, "%s: wrote %s: %d sensors, %d frame sets, %d views in %.2f s\n",
                         kTool, out_dir.c_str(), summary.sensors, summary.frames, summary.views,
                         watch.seconds());
        }
        return 0;
    } catch (const UsageError& e) {
        std::cerr << kTool << ": error: " << e.what() << rgbd::option_named_by(e.what(), given)
                  << "\n";
        return 2;
    } catch (const std::exception& e) {
        std::cerr << kTool << ": error: " << e.what() << "\n";
        return 1;
    }
}
