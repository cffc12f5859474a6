// rgbd-upsample: colour-guided 3D super-resolution of every view of a stream (docs/algorithms.md
// §5).
#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include "algorithms/upsample/upsample_view.hpp"
#include "cli/common/tool.hpp"
#include "io/capture_folder.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;
namespace fs = std::filesystem;

namespace {

std::string view_label(const PointCloud& cloud) {
    std::string label = "view " + std::to_string(cloud.view.id);
    if (!cloud.view.source.empty()) label += " (" + cloud.view.source + ")";
    return label;
}

/// The capture folders the tool has opened, by path.
class Captures {
public:
    explicit Captures(std::string forced) : forced_(std::move(forced)) {}

    /// The capture of a view: --capture, else the folder its source lies in
    /// (CAPTURE/<sensor>/depth/NNNNNN.png, or a flat layout: the nearest ancestor that opens).
    const io::Capture& of(const PointCloud& cloud) {
        if (!forced_.empty()) return open(forced_);
        const std::string& source = cloud.view.source;
        if (source.empty())
            throw InputError(
                view_label(cloud) +
                ": no rgbd:view.source to find its capture folder; pass --capture DIR");
        fs::path dir = fs::path(source).parent_path();
        std::vector<fs::path> candidates;
        for (int up = 0; up < 3 && !dir.empty(); ++up, dir = dir.parent_path())
            candidates.insert(candidates.begin(), dir);  // CAPTURE/<sensor>/depth first
        for (const fs::path& c : candidates) {
            if (failed_.count(c.string())) continue;
            try {
                return open(c.string());
            } catch (const Error&) {
                failed_.insert({c.string(), true});
            }
        }
        throw InputError(view_label(cloud) + ": no capture folder found around " + source +
                         "; pass --capture DIR");
    }

private:
    const io::Capture& open(const std::string& path) {
        auto it = cache_.find(path);
        if (it == cache_.end()) it = cache_.emplace(path, io::open_capture(path)).first;
        return it->second;
    }
    std::string forced_;
    std::map<std::string, io::Capture> cache_;
    std::map<std::string, bool> failed_;
};

void run_upsample(cli::Context& ctx) {
    upsample::UpsampleOptions options;
    try {
        options.neighbors = ctx.get<int>("neighbors");
        if (ctx.options().count("midpoints")) options.method = upsample::UpsampleMethod::kMidpoints;
        options.sigma_spatial = ctx.get<double>("sigma-spatial");
        options.sigma_color = ctx.get<double>("sigma-color");
        options.grazing_max_deg = ctx.get<double>("grazing-deg");
        options.theta_max_deg = ctx.get<double>("theta-max-deg");
        options.check();
    } catch (const InputError& e) {
        throw cli::UsageError(e.what());
    }
    Captures captures(ctx.options().count("capture") ? ctx.get<std::string>("capture") : "");
    std::unique_ptr<cli::ProgressBar> bar;  // from the first view on: bad input fails without it
    ctx.for_each_view([&](PointCloud& cloud) {
        if (!bar) bar.reset(new cli::ProgressBar(ctx.progress("upsample")));
        if (!cloud.view.has_grid())
            throw InputError(view_label(cloud) +
                             ": the view has no pixel grid (rgbd:grid); rgbd-upsample needs "
                             "organised views from rgbd-cloud");
        if (cloud.empty()) {
            ctx.warn(view_label(cloud) + " has no points");
            return;
        }
        if (!cloud.view.frame_index)
            throw InputError(view_label(cloud) + ": no rgbd:view.frame_index to find its frame");
        const io::Capture& capture = captures.of(cloud);
        std::string sensor = cloud.view.sensor;
        if (sensor.empty() && capture.rig.sensors.size() == 1) sensor = capture.rig.sensors[0].id;
        const auto position = capture.find_frame(sensor, *cloud.view.frame_index);
        if (!position)
            throw InputError(view_label(cloud) + ": frame " +
                             std::to_string(*cloud.view.frame_index) + " of sensor '" + sensor +
                             "' is not in capture " + capture.root.string());
        const io::FrameRecord& record = capture.frames.at(sensor)[*position];
        if (record.color.empty())
            throw InputError(view_label(cloud) + ": frame " + std::to_string(record.index) +
                             " of sensor '" + sensor + "' has no colour image in capture " +
                             capture.root.string());
        const RgbdFrame frame = io::load_frame(capture, sensor, *position);
        Report report = upsample::upsample_view(cloud, frame, options, bar->callback());
        report["view"] = cloud.view.id;
        ctx.add_document_metrics(report);
        ctx.info(view_label(cloud) + ": " + report.dump());
    });
}

const cli::ToolSpec kSpec{
    .name = "rgbd-upsample",
    .usage =
        "rgbd-upsample [--neighbors 4|8] [--midpoints] [--capture DIR] [options] [FILE...] > "
        "views.ply",
    .description =
        "Colour-guided 3D super-resolution, one view at a time (docs/algorithms.md §5). The "
        "colour camera has about 3x the depth camera's resolution (Kinect v2), so each depth "
        "point gets new points at the 4 (N, S, E, W) or 8 colour pixels around the colour "
        "pixel it maps to. A new point lies on the colour camera's ray through its pixel, at a "
        "depth interpolated from the surrounding depth samples with a joint bilateral weight "
        "(colour-pixel distance x colour similarity); it takes that colour pixel's colour, is "
        "flagged synthetic = 1 and gets a confidence (parent confidence x mean colour weight). "
        "Depth pixels next to a depth discontinuity get no new points, so nothing is placed in "
        "the gaps. --midpoints adds midpoints of grid neighbours instead (E, S; + SE, SW with "
        "8). When the colour image has the depth's resolution (registered data), the steps "
        "become 1/3 pixel and the colour is interpolated: more points, but no new colour "
        "detail.\n\n"
        "Needs organised views from rgbd-cloud (rgbd:grid, pixel) and their RGB-D frames: the "
        "frame is found by the view's sensor and frame_index in the capture folder given with "
        "--capture, by default the folder the view's source lies in (rgbd:view.source = "
        "CAPTURE/<sensor>/depth/NNNNNN.png, so CAPTURE = its grandparent's parent; flat "
        "layouts: the nearest ancestor folder that opens as a capture). Run before rgbd-align: "
        "alignment estimates poses on the original points only and moves all points.",
    .example =
        "rgbd-cloud cap/ | rgbd-clean | rgbd-upsample --neighbors 8 | rgbd-align | rgbd-mesh "
        "-o bust.ply",
    .add_options = [](cli::po::options_description& o) {
        o.add_options()("neighbors", cli::value(upsample::UpsampleOptions{}.neighbors, "4|8"),
                        "new points per depth point: 4 or 8 colour-pixel neighbours")(
            "midpoints", "Algorithm B: midpoints of grid neighbours instead of colour pixels")(
            "capture", cli::value<std::string>("DIR"),
            "capture folder holding the views' frames (default: derived from "
            "rgbd:view.source)")("sigma-spatial",
                                 cli::value(upsample::UpsampleOptions{}.sigma_spatial, "X"),
                                 "spatial sigma of the bilateral weight, in depth pixels")(
            "sigma-color", cli::value(upsample::UpsampleOptions{}.sigma_color, "X"),
            "colour sigma of the bilateral weight, mean absolute RGB difference in 8-bit "
            "levels")(
            "grazing-deg", cli::value(upsample::UpsampleOptions{}.grazing_max_deg, "DEG"),
            "no new point where the colour ray meets the surface more obliquely than this")(
            "theta-max-deg", cli::value(upsample::UpsampleOptions{}.theta_max_deg, "DEG"),
            "discontinuity gate: largest surface slope a depth step may come from");
    }};

}  // namespace

int main(int argc, char** argv) { return cli::run_tool(argc, argv, kSpec, run_upsample); }
