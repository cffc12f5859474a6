// The pipeline stages as the tools see them: the library calls of pipeline/stages.hpp and
// pipeline/fill_stage.hpp under rgbd::cli, plus what needs the tool's context (frame selection
// from the command line's --frameset/--frames, reading the input stream's views).
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "io/capture_folder.hpp"
#include "pipeline/fill_stage.hpp"
#include "pipeline/stages.hpp"
#include "toolkit/point_cloud.hpp"

namespace rgbd::cli {

class Context;

using pipeline::align_stage;
using pipeline::evaluate_poses;
using pipeline::evaluate_surface;
using pipeline::ExtractionOptions;
using pipeline::fill_stage;
using pipeline::FillStageOptions;
using pipeline::load_result;
using pipeline::load_view;
using pipeline::LoadedResult;
using pipeline::mechanism_color;
using pipeline::mesh_stage;
using pipeline::object_centre;
using pipeline::read_gt_poses;
using pipeline::view_from_frame;
using pipeline::colour_hidden_points;

/// Which frames of a capture become views: (sensor id, position in its frame list).
/// Multi-sensor captures: the sensors of frame set `frameset`; single-sensor sequences: the
/// positions in `frames` ("A:B[:STEP]", empty = all). Throws UsageError / InputError.
std::vector<std::pair<std::string, std::size_t>> select_frames(
    const io::Capture& capture, long long frameset, const std::string& frames,
    const std::vector<std::string>& sensors, const Context* context);

/// Reads every document of the tool's inputs as point views; a mesh document is an
/// InputError naming the tool and the document.
std::vector<PointCloud> read_point_views(Context& context);

/// Warnings for the colour cameras whose pose refinement a texture report (texture_mesh's, with
/// --refine-colour) refused, and a note of the photometric residual before and after.
void warn_refused_colour_poses(Context& context, const Report& texture_report);

}  // namespace rgbd::cli
