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
    cli::ExtractionOptions extraction;
    extraction.crop_radius_m = ctx.get<double>("crop-radius-m");
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
    if (centre && extraction.crop_radius_m > 0)
        ctx.info("object centre (" + std::to_string(centre->x()) + ", " +
                 std::to_string(centre->y()) + ", " + std::to_string(centre->z()) + ")");
    auto bar = ctx.progress("clouds");
    int view_id = 0;
    for (const auto& [id, position] : jobs) {
        Report report;
        io::Document document;
        document.cloud =
            cli::load_view(capture, id, position, view_id, options, centre, extraction, report);
        if (document.cloud.empty())
            ctx.warn("view " + std::to_string(view_id) + " (" + id + "): no points left");
        ctx.add_document_metrics(report);
        ctx.info("view " + std::to_string(view_id) + " (" + id +
                 "): " + std::to_string(document.cloud.size()) + " points");
        ctx.write(document);
        ++view_id;
        bar.update(static_cast<double>(view_id) / jobs.size());
    }
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
        "object by a depth window and, when the capture has one, the object mask. Points stay "
        "in the sensor frame; the view's world_from_sensor pose travels in the metadata.\n\n"
        "Multi-sensor captures emit the sensors of one frame set (--frameset); single-sensor "
        "sequences (turntable, hand-held) emit every frame (--frames) as a view.",
    .example =
        "rgbd-cloud cap/ --frameset 0 | rgbd-clean --statistical | rgbd-align | rgbd-mesh -o "
        "bust.ply",
    .reads_stream = false,
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
            "crop-radius-m", cli::value(cli::ExtractionOptions{}.crop_radius_m, "M"),
            "keep points within this distance of the object centre, where the sensors' optical "
            "axes converge (0 = no crop; skipped when the poses do not tell a centre)");
    }};

}  // namespace

int main(int argc, char** argv) { return cli::run_tool(argc, argv, kSpec, run_cloud); }
