// rgbd-cloud: capture folder -> view stream (one organised, coloured cloud per sensor view).
#include <filesystem>
#include <set>
#include <sstream>

#include "algorithms/frames/depth_to_cloud.hpp"
#include "cli/common/stages.hpp"
#include "cli/common/tool.hpp"
#include "io/capture_folder.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;

namespace {

std::set<std::string> split_ids(const std::string& text) {
    std::set<std::string> ids;
    std::stringstream ss(text);
    std::string item;
    while (std::getline(ss, item, ','))
        if (!item.empty()) ids.insert(item);
    return ids;
}

void run_cloud(cli::Context& ctx) {
    if (ctx.inputs().size() != 1) throw cli::UsageError("expected exactly one capture folder");
    const std::string root = ctx.inputs().front();

    // The options first: a bad value is a usage error before any input is read.
    frames::CloudOptions options;
    options.z_min_m = ctx.get<double>("z-min");
    options.z_max_m = ctx.get<double>("z-max");
    options.use_mask = !ctx.options().count("no-mask");
    try {
        options.check();
    } catch (const InputError& e) {
        throw cli::UsageError(e.what());
    }
    pipeline::SubjectStageOptions extraction;
    extraction.crop_radius_m = ctx.get<double>("crop-radius-m");
    extraction.enabled = !ctx.options().count("no-extract");
    extraction.subject.remove_ground = !ctx.options().count("keep-ground");
    if (!(extraction.crop_radius_m >= 0)) throw cli::UsageError("--crop-radius-m must be >= 0");
    const io::Capture capture = io::open_capture(root);
    std::vector<std::string> sensors;
    if (ctx.options().count("sensors")) {
        const auto ids = split_ids(ctx.get<std::string>("sensors"));
        sensors.assign(ids.begin(), ids.end());
    }
    const auto jobs = cli::select_frames(
        capture, ctx.get<long long>("frameset"),
        ctx.options().count("frames") ? ctx.get<std::string>("frames") : std::string(), sensors,
        &ctx);
    const auto centre = cli::object_centre(capture, jobs);
    if (centre)
        ctx.info("the sensors' axes converge at (" + std::to_string(centre->x()) + ", " +
                 std::to_string(centre->y()) + ", " + std::to_string(centre->z()) + ")");
    // All views of the selection first: the object extraction looks at them together.
    auto bar = ctx.progress("clouds");
    std::vector<PointCloud> views;
    std::vector<Report> reports;
    for (const auto& [id, position] : jobs) {
        Report report;
        views.push_back(cli::load_view(capture, id, position, static_cast<int>(views.size()),
                                       options, centre, /*extraction=*/{0.0}, report));
        reports.push_back(std::move(report));
        bar.update(0.8 * views.size() / jobs.size());
    }
    Report extraction_report;
    try {
        extraction_report = pipeline::extract_stage(views, centre, extraction);
    } catch (const InputError& e) {
        throw InputError(root + ": " + e.what());
    }
    if (!extraction_report.is_null()) {
        if (extraction_report.contains("note"))
            ctx.warn(extraction_report["note"].get<std::string>());
        if (extraction_report.contains("ground") && extraction_report["ground"].contains("note") &&
            !extraction.crop_radius_m)
            ctx.info("extraction: " + extraction_report["ground"]["note"].get<std::string>());
        ctx.metrics()["extraction"] = extraction_report;
    }
    for (std::size_t v = 0; v < views.size(); ++v) {
        reports[v]["points"] = views[v].size();
        io::Document document;
        document.cloud = std::move(views[v]);
        if (document.cloud.empty())
            ctx.warn("view " + std::to_string(v) + " (" + jobs[v].first + "): no points left");
        ctx.add_document_metrics(reports[v]);
        ctx.info("view " + std::to_string(v) + " (" + jobs[v].first +
                 "): " + std::to_string(document.cloud.size()) + " points");
        ctx.write(document);
    }
    bar.update(1.0);
}

const cli::ToolSpec kSpec{
    .name = "rgbd-cloud",
    .usage = "rgbd-cloud CAPTURE_DIR [options] > views.ply",
    .description =
        "Turns the frames of a capture folder (capture folder v1, TUM RGB-D, Open3D/Redwood or "
        "a folder of frames with OpenCV camera files) into a stream of coloured point clouds, "
        "one per sensor view: depth pixels are back-projected with the depth camera's "
        "intrinsics, mapped into the colour camera (with an occlusion test, so a point hidden "
        "from the colour camera is not painted with its occluder's colour) and cut to the "
        "object by a depth window and, when the capture has one, the object mask. Then the object "
        "extraction over all views of the selection: the ground (the lowest large plane "
        "facing the cameras' up) is removed with a margin from the sensor noise and its plane "
        "written into each view's metadata; of what is left, the connected regions the sensors "
        "look at together are the subject, and walls, other people and clutter away from it are "
        "dropped (docs/method.md). Points stay "
        "in the sensor frame; the view's world_from_sensor pose travels in the metadata.\n\n"
        "Multi-sensor captures emit the sensors of one frame set (--frameset); single-sensor "
        "sequences (turntable, hand-held) emit every frame (--frames) as a view.",
    .example =
        "rgbd-cloud cap/ --frameset 0 | rgbd-clean --statistical | rgbd-align | rgbd-mesh -o "
        "bust.ply",
    .reads_stream = false,
    .ranges = {{"z-min", Range::closed(0, 100), "m"},
               {"z-max", Range::closed(0, 100), "m"},
               {"crop-radius-m", Range::closed(0, 100), "m"}},
    .add_options = [](cli::po::options_description& o) {
        o.add_options()("frameset", cli::value<long long>(0, "N"),
                        "frame set to emit (multi-sensor captures)")(
            "frames", cli::value<std::string>("A:B[:STEP]"),
            "frame positions to emit per sensor (default: all for single-sensor captures)")(
            "sensors", cli::value<std::string>("ID,..."), "only these sensor ids (default: all)")(
            "z-min", cli::value(frames::CloudOptions{}.z_min_m, "M"),
            "depth window near limit in metres (0 = the sensor's range)")(
            "z-max", cli::value(frames::CloudOptions{}.z_max_m, "M"),
            "depth window far limit in metres (0 = the sensor's range)")(
            "no-mask", "ignore the capture's object masks")(
            "crop-radius-m", cli::value(pipeline::SubjectStageOptions{}.crop_radius_m, "M"),
            "override of the object extraction's extent: keep points within this distance of "
            "where the sensors' optical axes converge (0 = the subject's extent from the data; "
            "skipped when the poses do not tell a centre)")(
            "keep-ground", "object extraction: keep the ground (floor, platter) in the views")(
            "no-extract", "no object extraction: every point in the depth window is kept");
    }};

}  // namespace

int main(int argc, char** argv) { return cli::run_tool(argc, argv, kSpec, run_cloud); }
