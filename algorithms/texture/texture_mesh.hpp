// Texturing a mesh from calibrated colour images, the whole chain (rgbd-texture,
// rgbd-reconstruct -o model.obj|glb; docs/algorithms.md "Texturing"): per-face view selection
// (view_selection.hpp), global colour adjustment (colour_adjustment.hpp), charts and atlas
// (atlas.hpp); faces no camera sees keep the mesh's vertex colours as flat colours. After
// Waechter, Moehrle and Goesele, "Let there be color! Large-scale texturing of 3D
// reconstructions", ECCV 2014 (without their photo-consistency check and local seam levelling).
// Optionally, first, the colour cameras' poses are refined against the mesh by photometric
// consistency (colour_pose_refinement.hpp) and the chain runs with the refined poses.
// See also: surface_colour.hpp (the colour error of a model against the images).
#pragma once

#include <vector>

#include "algorithms/texture/atlas.hpp"
#include "algorithms/texture/colour_adjustment.hpp"
#include "algorithms/texture/colour_pose_refinement.hpp"
#include "algorithms/texture/photo_consistency.hpp"
#include "algorithms/texture/seam_levelling.hpp"
#include "algorithms/texture/view_selection.hpp"
#include "toolkit/mesh.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"
#include "toolkit/textured_mesh.hpp"

namespace rgbd::texture {

struct TextureOptions {
    RefineOptions refine;  ///< off by default (--refine-colour)
    SelectionOptions selection;
    AdjustOptions adjust;
    ConsistencyOptions consistency;
    LevellingOptions levelling;
    AtlasOptions atlas;

    void check() const;
};

/// Textures `mesh` (world frame) from `views`. Report: faces, views, per-step times and
/// counts (refine, when enabled; adjust; consistency; selection: unseen faces, relabelled;
/// levelling; atlas; "up": the result's `up`, sensors_up of the colour cameras at agreement 0.7,
/// when they agree). Throws InputError when there are no views, a view's image is missing or of
/// the wrong size, or no face of the mesh is seen by any view.
TexturedMesh texture_mesh(const Mesh& mesh, const std::vector<TextureView>& views,
                          const TextureOptions& options, Report& report,
                          const Progress& progress = {});

}  // namespace rgbd::texture
