// rgbd-eval --colour CAPTURE: the colour error of a model (textured OBJ / glb, or vertex
// colours) against the capture's colour images (algorithms/texture/surface_colour.hpp).
#pragma once

#include <string>

#include "cli/common/stages.hpp"
#include "cli/common/tool.hpp"
#include "toolkit/report.hpp"

namespace rgbd::cli {

/// The result file as rgbd-eval's other modes read it: a .glb as its mesh (geometry and vertex
/// colours), anything else through load_result.
LoadedResult load_eval_input(const std::string& path);

/// The "colour" report of rgbd-eval: `model_path` read with io::read_textured_mesh, compared with
/// the colour images of --colour's capture (frames: --colour-views' views, else --frameset /
/// --frames), posed by --colour-views' refined poses, else the capture's truth
/// (gt/world_from_depth.json, synthetic captures), else the capture's own poses.
Report colour_report(Context& ctx, const std::string& model_path);

}  // namespace rgbd::cli
