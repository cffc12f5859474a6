// rgbd-render: a PNG picture of a mesh or a point cloud, in software (no GPU, no display).
#include <filesystem>
#include <sstream>

#include "algorithms/evaluation/metrics.hpp"
#include "algorithms/render/picture.hpp"
#include "cli/common/stages.hpp"
#include "cli/common/tool.hpp"
#include "io/capture_folder.hpp"
#include "io/mesh_io.hpp"
#include "io/textured_mesh_io.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;
namespace fs = std::filesystem;

namespace {

Eigen::Vector3d parse_up(const std::string& text) {
    if (text == "x" || text == "+x") return Eigen::Vector3d::UnitX();
    if (text == "y" || text == "+y") return Eigen::Vector3d::UnitY();
    if (text == "z" || text == "+z") return Eigen::Vector3d::UnitZ();
    if (text == "-x") return -Eigen::Vector3d::UnitX();
    if (text == "-y") return -Eigen::Vector3d::UnitY();
    if (text == "-z") return -Eigen::Vector3d::UnitZ();
    const auto v = cli::parse_doubles(text, "up");
    if (v.size() != 3) throw cli::UsageError("--up: give an axis (x, -y, ...) or X,Y,Z");
    const Eigen::Vector3d up(v[0], v[1], v[2]);
    if (!up.allFinite() || !(up.norm() > 0)) throw cli::UsageError("--up must be non-zero");
    return up;
}

void run_render(cli::Context& ctx) {
    if (ctx.inputs().size() != 1) throw cli::UsageError("expected exactly one INPUT file");
    const std::string out = ctx.output_path();
    if (out.empty()) throw cli::UsageError("give the picture file with -o PICTURE.png");
    std::string ext = fs::path(out).extension().string();
    for (auto& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (ext != ".png") throw cli::UsageError("-o " + out + ": the picture must be a .png file");

    render::CameraOptions camera_options;
    render::PictureOptions picture_options;
    std::optional<Eigen::Vector3d> up;
    try {
        camera_options.view = render::parse_view_direction(ctx.get<std::string>("view"));
        camera_options.width = ctx.get<int>("width");
        camera_options.height = ctx.get<int>("height");
        if (ctx.has("azimuth")) camera_options.azimuth_deg = ctx.get<double>("azimuth");
        if (ctx.has("elevation")) camera_options.elevation_deg = ctx.get<double>("elevation");
        camera_options.check();
        picture_options.point_radius_px = ctx.get<double>("point-size");
        if (ctx.has("scalar-min")) picture_options.scalar_min = ctx.get<double>("scalar-min");
        if (ctx.has("scalar-max")) picture_options.scalar_max = ctx.get<double>("scalar-max");
        picture_options.check();
    } catch (const InputError& e) {
        throw cli::UsageError(e.what());
    }
    if (ctx.has("up")) up = parse_up(ctx.get<std::string>("up"));
    const bool distance = ctx.has("scalar") && ctx.get<std::string>("scalar") == "distance";
    if (distance != ctx.has("reference"))
        throw cli::UsageError("--scalar distance and --reference go together");
    if (distance) {  // the bar is in mm, the values in metres
        picture_options.scalar_display_scale = 1000.0;
        picture_options.scalar_label = "mm";
        if (picture_options.scalar_min) *picture_options.scalar_min /= 1000.0;
        if (picture_options.scalar_max) *picture_options.scalar_max /= 1000.0;
    }

    const std::string input = ctx.inputs().front();
    // A textured model (.obj with its MTL and atlas, .glb) is drawn with its texture.
    const bool textured_file = io::is_textured_format(input);
    cli::LoadedResult loaded;
    if (!textured_file) loaded = cli::load_result(input);
    render::Geometry geometry;
    try {
        if (textured_file)
            geometry = render::from_textured_mesh(io::read_textured_mesh(input));
        else
            geometry =
                loaded.mesh ? render::from_mesh(*loaded.mesh) : render::from_views(loaded.views);
    } catch (const InputError& e) {
        throw InputError(input + ": " + e.what());
    }
    if (geometry.vertices.empty()) throw InputError(input + ": nothing to draw (no points)");
    if (ctx.has("scalar") && !distance) {
        const std::string name = ctx.get<std::string>("scalar");
        if (loaded.mesh || textured_file)
            throw cli::UsageError("--scalar " + name +
                                  ": meshes carry no value properties; use distance");
        for (const auto& v : loaded.views) {
            const auto map = v.float_map(name.c_str());
            if (!map)
                throw InputError(input + ": view " + std::to_string(v.view.id) +
                                 " has no float property '" + name + "'");
            for (auto i : v.points) geometry.scalars.push_back((*map)[i]);
        }
        picture_options.scalar_label = name;
    }
    if (distance) {
        const std::string ref = ctx.get<std::string>("reference");
        geometry.scalars = evaluation::distances_to_surface(geometry.vertices, io::read_mesh(ref));
    }
    geometry.check(input);
    Eigen::Vector3d lo = geometry.vertices.front(), hi = lo;
    for (const auto& v : geometry.vertices) {
        lo = lo.cwiseMin(v);
        hi = hi.cwiseMax(v);
    }
    const render::Orientation orientation =
        render::guess_orientation(geometry.sensors, 0.5 * (lo + hi), up);
    Stopwatch watch;
    const render::Camera camera =
        render::fit_camera(geometry.vertices, orientation, camera_options);
    const render::Picture picture = render::render_picture(geometry, camera, picture_options);
    const double render_time = watch.seconds();
    io::write_image_atomic(out, picture.image);

    Report& m = ctx.metrics()["render"];
    const auto& k = camera.intrinsics;
    m["kind"] = geometry.is_mesh() ? "mesh" : "points";
    m["vertices"] = geometry.vertices.size();
    m["triangles"] = geometry.triangles.size();
    m["colors"] = !geometry.colors.empty();
    m["textured"] = geometry.is_textured();
    m["intrinsics"] = {{"width", k.width}, {"height", k.height}, {"fx", k.fx},
                       {"fy", k.fy},       {"cx", k.cx},         {"cy", k.cy}};
    Report pose = Report::array();
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) pose.push_back(camera.world_from_camera.matrix()(r, c));
    m["world_from_camera"] = pose;
    m["up"] = {orientation.up.x(), orientation.up.y(), orientation.up.z()};
    m["front"] = {orientation.front.x(), orientation.front.y(), orientation.front.z()};
    m["covered_pixels"] = picture.covered_pixels;
    if (picture.color_bar) {
        const cv::Rect& b = *picture.color_bar;
        m["color_bar"] = {{"x", b.x}, {"y", b.y}, {"width", b.width}, {"height", b.height}};
        m["scalar_min"] = picture.scalar_min;
        m["scalar_max"] = picture.scalar_max;
    }
    m["time_s"] = render_time;
    ctx.info("picture: " + out + " (" + std::to_string(picture.image.cols) + "x" +
             std::to_string(picture.image.rows) + ")");
}

const cli::ToolSpec kSpec{
    .name = "rgbd-render",
    .usage = "rgbd-render INPUT -o PICTURE.png [options]",
    .description =
        "Draws a mesh (.ply/.off/.obj; a textured .obj or .glb with its texture) or points (a view "
        "stream, .ply/.pcd/.xyz) into a PNG "
        "picture, in software. The camera looks at the object's bounding box (0.2%-99.8% "
        "quantiles, so a few stray points do not shrink the object) and fits it into the "
        "picture; by default from a three-quarter view on the sensors' side (35 degrees right "
        "of the front, 20 degrees above), with up from the sensors' poses, else +y. Vertex "
        "colours (or the texture) are used when present, else grey Lambert shading. Points are "
        "splatted as "
        "discs with a depth test. --scalar colours by a per-vertex value (turbo colour map) "
        "and adds a colour bar: 'distance' (to --reference, in mm) or a float property of a "
        "point file (confidence, scale, ...). --metrics gets the camera.",
    .example = "rgbd-render bust.ply -o bust.png --view front --width 800 --height 800",
    .writes_stream = false,
    .reads_stream = false,
    .writes_file = true,
    .ranges = {{"azimuth", Range::closed(-360, 360), "degrees"}},
    .scopes = {{{"scalar"}, {"scalar-min", "scalar-max", "reference"}}},
    .add_options = [](cli::po::options_description& o) {
        o.add_options()("view", cli::value<std::string>("auto", "NAME"),
                        "auto, front, back, left, right or top")(
            "azimuth", cli::value<double>("DEG"),
            "camera azimuth around up (0 = front, 90 = from the right)")(
            "elevation", cli::value<double>("DEG"),
            "camera elevation (0 = level, 90 = from above)")(
            "up", cli::value<std::string>("AXIS|X,Y,Z"),
            "world up direction (default: from the sensors' poses, else +y)")(
            "width", cli::value(render::CameraOptions{}.width, "PX"), "picture width")(
            "height", cli::value(render::CameraOptions{}.height, "PX"), "picture height")(
            "point-size", cli::value(render::PictureOptions{}.point_radius_px, "PX"),
            "splat radius of points in pixels (0 = from the point spacing)")(
            "scalar", cli::value<std::string>("NAME"),
            "colour by a value: 'distance' (to --reference) or a float point property")(
            "reference", cli::value<std::string>("MESH"),
            "reference surface for --scalar distance")(
            "scalar-min", cli::value<double>("V"),
            "value at the bottom of the colour bar (distance: mm; default 0 or the minimum)")(
            "scalar-max", cli::value<double>("V"),
            "value at the top of the colour bar (distance: mm; default the 98th percentile)");
    }};

}  // namespace

int main(int argc, char** argv) { return cli::run_tool(argc, argv, kSpec, run_render); }
