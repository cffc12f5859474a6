// The result end of the Python API (docs/python.md): texture(), evaluate(), evaluate_poses() and
// the whole method, reconstruct(). Like bindings_stages.cpp, each maps its keyword options onto
// the option structs as its tool maps its command line (cli/rgbd_texture.cpp, rgbd_eval.cpp,
// rgbd_reconstruct.cpp) and calls the same library functions with the GIL released.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "algorithms/texture/texture_mesh.hpp"
#include "cli/common/stages.hpp"
#include "cli/common/tool.hpp"
#include "io/capture_folder.hpp"
#include "io/mesh_io.hpp"
#include "io/textured_mesh_io.hpp"
#include "pipeline/reconstruct.hpp"
#include "pipeline/stages.hpp"
#include "pipeline/texture_views.hpp"
#include "python/bindings.hpp"
#include "toolkit/error.hpp"

namespace rgbd::python {
namespace {

using namespace pybind11::literals;

// ---- texture ----------------------------------------------------------------------------------

py::object texture(const py::object& mesh_arg, const py::object& capture_arg,
                   const std::filesystem::path& output, const py::kwargs& kwargs) {
    Options o("texture", kwargs);
    const Mesh& mesh = mesh_arg.cast<const Mesh&>();
    RGBD_CHECK(io::is_textured_format(output),
               output.string() + ": texture writes a .obj (with .mtl and .png) or a .glb");
    RGBD_CHECK(mesh.number_of_faces() > 0, "texture: the mesh has no faces");
    const io::Capture capture = capture_of(capture_arg);
    long long frameset = 0;
    std::string frames;
    o.get("frameset", frameset);
    o.get("frames", frames);
    const py::object views_arg = o.object("views");
    texture::TextureOptions options;
    double angle_deg = std::acos(options.selection.min_cos) * 180.0 / M_PI;
    o.get("max_angle_deg", angle_deg);
    check_range("max_angle_deg", angle_deg, Range::closed(1, 89), "degrees");
    options.selection.min_cos = std::cos(angle_deg * M_PI / 180.0);
    if (o.flag("no_consistency")) options.consistency.enabled = false;
    if (o.flag("no_levelling")) options.levelling.enabled = false;
    if (o.flag("refine_colour")) options.refine.enabled = true;
    o.get("refine_colour_iterations", options.refine.iterations);
    ProgressBridge bridge(o.object("progress"));
    o.done();
    options.check();
    // As rgbd-texture: the frames (and refined poses) of aligned views, else the selection.
    std::vector<PointCloud> aligned;
    if (!views_arg.is_none())
        for (const PointCloud* v : views_of(views_arg, "texture")) aligned.push_back(*v);
    const auto selection = aligned.empty() ? selected_frames(capture, frameset, frames, {})
                                           : pipeline::frames_of_views(capture, aligned);
    Report report;
    without_gil(bridge, [&] {
        const auto views =
            pipeline::load_texture_views(capture, selection, aligned.empty() ? nullptr : &aligned);
        const TexturedMesh model =
            texture::texture_mesh(mesh, views, options, report, bridge.stage("texture"));
        io::write_textured_mesh(output, model, "rgbd_toolkit.texture");
        return 0;
    });
    return to_python(report);
}

// ---- evaluate ---------------------------------------------------------------------------------

py::object evaluate(const py::object& result_arg, const py::object& reference_arg,
                    const py::kwargs& kwargs) {
    Options o("evaluate", kwargs);
    evaluation::MetricOptions options;
    std::vector<double> tau_mm = {2, 5};
    o.get("tau_mm", tau_mm);
    options.taus_m.clear();
    for (double t : tau_mm) {
        check_range("tau_mm", t, Range::open_closed(0, 1e6), "mm");
        options.taus_m.push_back(t / 1000.0);
    }
    double invented_tau_mm = options.invented_tau_m * 1000.0;
    o.get("invented_tau_mm", invented_tau_mm);
    check_range("invented_tau_mm", invented_tau_mm, Range::open_closed(0, 1e6), "mm");
    options.invented_tau_m = invented_tau_mm / 1000.0;
    o.get("samples", options.samples);
    options.seed = 0;  // the tools' --seed default
    o.get("seed", options.seed);
    o.done();
    options.check();

    pipeline::LoadedResult result;
    if (py::isinstance<Mesh>(result_arg)) {
        result.mesh = result_arg.cast<Mesh>();
        RGBD_CHECK(result.mesh->number_of_faces() > 0, "the mesh has no faces");
    } else {
        for (const PointCloud* v : views_of(result_arg, "evaluate")) result.views.push_back(*v);
    }
    const Mesh reference = py::isinstance<Mesh>(reference_arg)
                               ? reference_arg.cast<Mesh>()
                               : io::read_mesh(reference_arg.cast<std::filesystem::path>());
    Report report;
    {
        py::gil_scoped_release release;
        report = pipeline::evaluate_surface(result, reference, options);
    }
    return to_python(report);
}

py::object evaluate_poses(const py::handle& views_arg, const std::filesystem::path& gt,
                          bool keep_gauge) {
    std::vector<PointCloud> views;
    for (const PointCloud* v : views_of(views_arg, "evaluate_poses")) {
        PointCloud pose_only;
        pose_only.view = v->view;
        views.push_back(std::move(pose_only));
    }
    Report report;
    {
        py::gil_scoped_release release;
        report = pipeline::evaluate_poses(views, gt.string(), !keep_gauge);
    }
    return to_python(report);
}

// ---- reconstruct ------------------------------------------------------------------------------

std::set<std::string> skip_option(const py::object& value) {
    std::set<std::string> skip;
    if (value.is_none()) return skip;
    if (py::isinstance<py::str>(value)) {
        // "a,b" as rgbd-reconstruct --skip takes it.
        std::stringstream in(value.cast<std::string>());
        std::string name;
        while (std::getline(in, name, ','))
            if (!name.empty()) skip.insert(name);
    } else {
        for (const auto& item : value) skip.insert(item.cast<std::string>());
    }
    std::string valid;
    for (const auto& s : pipeline::optional_stages()) valid += (valid.empty() ? "" : ", ") + s;
    for (const auto& s : skip)
        RGBD_CHECK(std::find(pipeline::optional_stages().begin(), pipeline::optional_stages().end(),
                             s) != pipeline::optional_stages().end(),
                   "skip: unknown stage '" + s + "' (valid: " + valid + ")");
    return skip;
}

py::object reconstruct(const py::object& capture_arg, const py::kwargs& kwargs) {
    Options o("reconstruct", kwargs);
    pipeline::ReconstructOptions options;
    options.skip = skip_option(o.object("skip"));
    o.get("method", options.mesh.method);
    options.mesh.watertight = !o.flag("open");
    if (o.flag("no_carve_closure")) options.mesh.carve_steps = 0;
    options.mesh.repair_self_intersections = o.flag("repair_self_intersections");
    options.mesh.check();
    int neighbors = options.upsample.neighbors;
    o.get("upsample", neighbors);
    RGBD_CHECK(neighbors == 0 || neighbors == 4 || neighbors == 8,
               "upsample must be 4 or 8 (0 = off), not " + std::to_string(neighbors));
    if (neighbors == 0)
        options.skip.insert("upsample");
    else
        options.upsample.neighbors = neighbors;
    options.upsample.check();
    options.noise_model = noise_model_option(o);
    std::string stand = "auto";
    o.get("stand", stand);
    try {
        options.stand = pipeline::parse_stand_mode(stand);
    } catch (const InputError& e) {
        throw InputError(std::string("stand: ") + e.what());
    }
    o.get("crop_radius_m", options.extraction.crop_radius_m);
    check_range("crop_radius_m", options.extraction.crop_radius_m, Range::closed(0, 100), "m");
    options.extraction.enabled = !o.flag("no_extract");
    options.extraction.subject.remove_ground = !o.flag("keep_ground");
    o.get("seed", options.seed);
    long long frameset = 0;
    std::string frames;
    o.get("frameset", frameset);
    o.get("frames", frames);
    ProgressBridge bridge(o.object("progress"));
    o.done();

    const io::Capture capture = capture_of(capture_arg);
    const auto jobs = selected_frames(capture, frameset, frames, {});
    // Warnings as Python warnings (RuntimeWarning), from the thread that runs the chain.
    pipeline::ReconstructHooks hooks;
    hooks.stage_begin = [&](const std::string& stage) { return bridge.stage(stage); };
    hooks.warn = [&](const std::string& message) {
        py::gil_scoped_acquire gil;
        try {
            py::module_::import("warnings")
                .attr("warn")(message, py::handle(PyExc_RuntimeWarning), 2);
        } catch (...) {
            bridge.fail();
        }
    };
    pipeline::ReconstructResult result =
        without_gil(bridge, [&] { return pipeline::reconstruct(capture, jobs, options, hooks); });
    Report report = result.report;
    report["capture"] = capture.root.string();
    report["stages"] = result.stages_report();
    report["timings_s"] = result.timings();
    py::object out = py::cast(std::move(result.mesh));
    out.attr("report") = to_python(report);
    return out;
}

}  // namespace

void bind_results(py::module_& m) {
    m.def("texture", &texture, "mesh"_a, "capture"_a, "output"_a,
          "A textured model of the mesh from the capture's colour images (rgbd-texture), written "
          "to `output` (.obj with .mtl and .png, or .glb). Options: views=None (aligned views: "
          "their frames and refined poses; else frameset=0 / frames='A:B[:STEP]' of the "
          "capture's own poses), max_angle_deg, no_consistency=False, no_levelling=False, "
          "refine_colour=False (refine the colour cameras' poses against the mesh first, as "
          "rgbd-texture --refine-colour), refine_colour_iterations=50, progress. Returns the "
          "report dict (selection, atlas, adjustment, levelling; refine with refine_colour).");
    m.def("evaluate", &evaluate, "result"_a, "reference"_a,
          "Surface metrics of a result (Mesh or list of views) against a reference (Mesh or "
          "path), as rgbd-eval --reference: tau_mm=[2, 5], invented_tau_mm=5, samples=200000, "
          "seed=0. Returns the report dict.");
    m.def("evaluate_poses", &evaluate_poses, "views"_a, "gt_poses"_a, "keep_gauge"_a = false,
          "Pose errors of the views against gt/world_from_depth.json (rgbd-eval --gt-poses).");
    m.def("reconstruct", &reconstruct, "capture"_a,
          "The whole method on a capture (rgbd-reconstruct; pipeline::reconstruct): clouds, "
          "distance cleaning, super-resolution, alignment, density cleaning, hole filling and "
          "a watertight mesh, with the same defaults, so the mesh equals the tool's. Options: "
          "skip=[...] (distance, upsample, density, fill; or 'a,b'), frameset=0, "
          "frames='A:B[:STEP]', noise_model='auto', crop_radius_m=0, keep_ground=False, "
          "no_extract=False, method='front', stand='auto', open=False, no_carve_closure=False, "
          "upsample=8, seed=0, "
          "progress=None. Warnings of the chain become RuntimeWarnings. Returns a Mesh with the "
          "report (stages, timings, per-view counts) as its `report` attribute.");
}

}  // namespace rgbd::python
