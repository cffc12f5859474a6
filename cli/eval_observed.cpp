#include "cli/eval_observed.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "algorithms/normals/estimate_normals.hpp"
#include "cli/common/stages.hpp"
#include "cli/common/temp_folder.hpp"
#include "io/capture_folder.hpp"
#include "io/mesh_io.hpp"
#include "toolkit/error.hpp"

namespace rgbd::cli {

namespace {

namespace fs = std::filesystem;

constexpr const char* kPeerScript = "open3d_observed.py";
constexpr const char* kPython = "/usr/bin/python3";

std::string number(double x) {
    std::ostringstream s;
    s.precision(17);
    s << x;
    return s.str();
}

/// POINTS.ply: float x y z nx ny nz (world), int view, uchar red green blue; views without
/// normals (fewer than 3 points) are left out. VIEWS.json: each view's pinhole and pose.
void write_peer_input(const fs::path& points, const fs::path& cameras,
                      const std::vector<PointCloud>& views) {
    std::size_t count = 0;
    for (const auto& v : views)
        if (v.points.has_normal_map()) count += v.size();
    std::ofstream out(points, std::ios::binary);
    out << "ply\nformat binary_little_endian 1.0\nelement vertex " << count << "\n";
    for (const char* p : {"x", "y", "z", "nx", "ny", "nz"}) out << "property float " << p << "\n";
    out << "property int view\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
           "end_header\n";
    Report json_views = Report::array();
    for (std::size_t k = 0; k < views.size(); ++k) {
        const PointCloud& v = views[k];
        RGBD_CHECK(v.view.intrinsics && v.view.world_from_sensor,
                   "observed view " + std::to_string(k) + " lacks intrinsics or a pose");
        const PinholeIntrinsics& in = *v.view.intrinsics;
        const Pose& pose = *v.view.world_from_sensor;
        Report m = Report::array();
        for (int r = 0; r < 4; ++r)
            for (int c = 0; c < 4; ++c) m.push_back(pose.matrix()(r, c));
        json_views.push_back({{"width", in.width},
                              {"height", in.height},
                              {"fx", in.fx},
                              {"fy", in.fy},
                              {"cx", in.cx},
                              {"cy", in.cy},
                              {"world_from_sensor", m}});
        if (!v.points.has_normal_map()) continue;
        std::optional<PointCloud::ColorMaps> colors;
        if (v.has_colors()) colors = v.colors();
        const std::int32_t id = static_cast<std::int32_t>(k);
        for (auto i : v.points) {
            const Eigen::Vector3f p = (pose * to_eigen(v.points.point(i))).cast<float>();
            const Eigen::Vector3f n = (pose.linear() * to_eigen(v.points.normal(i))).cast<float>();
            const float f[6] = {p.x(), p.y(), p.z(), n.x(), n.y(), n.z()};
            out.write(reinterpret_cast<const char*>(f), sizeof f);
            out.write(reinterpret_cast<const char*>(&id), sizeof id);
            const Rgb c = colors ? colors->get(i) : Rgb{160, 160, 160};
            const std::uint8_t rgb[3] = {c.r, c.g, c.b};
            out.write(reinterpret_cast<const char*>(rgb), 3);
        }
    }
    RGBD_CHECK_AS(IoError, out.good(), points.string() + ": cannot write");
    std::ofstream cam(cameras);
    cam << Report{{"views", json_views}}.dump() << "\n";
    RGBD_CHECK_AS(IoError, cam.good(), cameras.string() + ": cannot write");
}

/// Runs `command`; its output in `output`, the shell's exit code (128 + N for signal N).
int run_command(const std::string& command, std::string& output, const Context& ctx) {
    ctx.info("baseline: " + command);
    FILE* pipe = ::popen(command.c_str(), "r");
    RGBD_CHECK_AS(IoError, pipe != nullptr, "cannot run " + std::string(kPython));
    output.clear();
    char buf[4096];
    while (std::size_t n = std::fread(buf, 1, sizeof buf, pipe)) output.append(buf, n);
    const int status = ::pclose(pipe);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace

/// The comma-separated names of --baseline, each known and at most once.
std::vector<std::string> parse_baselines(const std::string& text, bool observed) {
    std::vector<std::string> names;
    std::stringstream ss(text);
    std::string name;
    while (std::getline(ss, name, ',')) {
        if (name != "screened-poisson" && name != "tsdf")
            throw UsageError("--baseline: unknown peer '" + name + "' (screened-poisson, tsdf)");
        if (name == "tsdf" && !observed)
            throw UsageError(
                "--baseline tsdf needs --observed CAPTURE (it fuses the depth "
                "images)");
        if (std::find(names.begin(), names.end(), name) != names.end())
            throw UsageError("--baseline names '" + name + "' twice");
        names.push_back(name);
    }
    if (names.empty()) throw UsageError("--baseline: no peer named");
    return names;
}

/// The observations of --observed CAPTURE: the frames --frameset / --frames select, their
/// observed subject; InputError naming the capture when it is not one.
pipeline::Observations load_observed(const Context& ctx,
                                     const evaluation::SubjectOptions& subject) {
    const std::string root = ctx.get<std::string>("observed");
    RGBD_CHECK(fs::is_directory(root), root + ": --observed needs a capture folder");
    const io::Capture capture = io::open_capture(root);
    const auto jobs = select_frames(
        capture, ctx.get<long long>("frameset"),
        ctx.options().count("frames") ? ctx.get<std::string>("frames") : std::string(), {}, &ctx);
    RGBD_CHECK(!jobs.empty(), root + ": no frame selected");
    frames::CloudOptions cloud;  // rgbd-cloud's depth window and masks
    cloud.z_min_m = ctx.get<double>("z-min");
    cloud.z_max_m = ctx.get<double>("z-max");
    cloud.check();
    // A synthetic capture's rig.json poses carry a calibration error that its truth does not:
    // the observations go where the sensors saw them.
    const std::map<std::string, Pose> truth = ctx.has("observed-capture-poses")
                                                  ? std::map<std::string, Pose>()
                                                  : pipeline::read_sensor_gt_poses(capture);
    return pipeline::load_observations(capture, jobs, cloud, subject,
                                       truth.empty() ? nullptr : &truth);
}

/// Observed metrics of one mesh; an error entry for a mesh without area.
Report observed_report(const Mesh& mesh, const std::vector<Eigen::Vector3d>& points,
                       const evaluation::ObservedOptions& options) {
    try {
        return evaluation::observed_metrics(mesh, points, options).to_json();
    } catch (const InputError& e) {
        return {{"error", e.what()}};
    }
}

std::vector<ObservedBaseline> run_observed_baselines(pipeline::Observations& observations,
                                                     const std::vector<std::string>& methods,
                                                     const ObservedPeerOptions& options,
                                                     const Context& ctx) {
    const fs::path script = find_peer_script(kPeerScript);
    RGBD_CHECK(fs::exists(kPython), std::string("--baseline with --observed needs Debian's ") +
                                        kPython + " with python3-open3d");
    normals::NormalOptions normal_options;  // kAuto: towards the sensor at the origin
    for (auto& v : observations.views)
        if (!v.points.has_normal_map() && v.size() >= 3)
            normals::estimate_normals(v, normal_options);
    const cli::TempFolder tmp("rgbd-eval-observed-");
    const fs::path points = tmp.path / "observed.ply", cameras = tmp.path / "views.json";
    write_peer_input(points, cameras, observations.views);
    std::vector<ObservedBaseline> out;
    for (const std::string& method : methods) {
        const fs::path mesh_file = tmp.path / (method + ".ply");
        std::string command =
            std::string(kPython) + " " + shell_quote(script.string()) + " --points " +
            shell_quote(points.string()) + " --views " + shell_quote(cameras.string()) +
            " --method " + method + " --out " + shell_quote(mesh_file.string()) + " --voxel " +
            number(options.tsdf_voxel_m) + " --trunc-voxels " + number(options.tsdf_trunc_voxels) +
            " --depth " + std::to_string(options.poisson_depth) + " --trim-quantile " +
            number(options.poisson_trim_quantile);
        std::string output;
        int code = run_command(command, output, ctx);
        Report extra = Report::object();
        if (code == 128 + SIGSEGV || code == 128 + SIGABRT) {
            // Open3D's multi-threaded Poisson solver crashes now and then (Open3D issue 6828,
            // PoissonRecon issue 298); one thread does not.
            ctx.warn("Open3D " + method + " crashed (exit code " + std::to_string(code) +
                     "); running it again on one thread");
            extra["threads"] = 1;
            code = run_command(command + " --threads 1", output, ctx);
        }
        if (code == 3)
            throw InputError("--baseline needs python3-open3d (apt-get install python3-open3d)");
        RGBD_CHECK_AS(AlgorithmError, code == 0,
                      "Open3D " + method + " failed (" + script.string() + " exit code " +
                          std::to_string(code) + ")");
        Report r = Report::parse(output, nullptr, false);
        RGBD_CHECK_AS(AlgorithmError, r.is_object() && r.contains("file"),
                      script.string() + ": unexpected output: " + output);
        ObservedBaseline b;
        b.name = method == "tsdf" ? "tsdf" : "screened_poisson";
        b.mesh = io::read_mesh(r["file"].get<std::string>());
        r.erase("file");
        r.update(extra);
        r["open3d"] = "0.16 (python3-open3d)";
        if (method == "tsdf") {
            r["voxel_mm"] = options.tsdf_voxel_m * 1000.0;
            r["sdf_trunc_mm"] = options.tsdf_voxel_m * options.tsdf_trunc_voxels * 1000.0;
        } else {
            r["depth"] = options.poisson_depth;
            r["trim_quantile"] = options.poisson_trim_quantile;
        }
        b.report = r;
        out.push_back(std::move(b));
    }
    return out;
}

fs::path find_peer_script(const std::string& name) {
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (!ec && fs::exists(exe.parent_path() / name)) return exe.parent_path() / name;
    const fs::path source = fs::path(RGBD_SOURCE_DIR) / "cli" / "peers" / name;
    if (fs::exists(source)) return source;
    throw IoError("cannot find " + name + " beside rgbd-eval or in " +
                  source.parent_path().string());
}

std::string shell_quote(const std::string& s) {
    std::string out = "'";
    for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return out + "'";
}

}  // namespace rgbd::cli
