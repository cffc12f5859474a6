// The whole method on a capture as one library call: the chain rgbd-reconstruct runs and the
// README's pipe composes stage by stage (docs/method.md):
//   clouds -> distance cleaning (per view) -> super-resolution (per view, colour finer than
//   depth) -> multi-view alignment -> density cleaning (aligned views) -> hole filling -> mesh.
// The tools keep argument mapping, files and progress bars; this computes.
#pragma once

#include <functional>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "algorithms/denoise/density_outliers.hpp"
#include "algorithms/denoise/distance_outliers.hpp"
#include "algorithms/frames/depth_to_cloud.hpp"
#include "algorithms/reconstruction/reconstruct_surface.hpp"
#include "algorithms/registration/icp.hpp"
#include "algorithms/render/picture.hpp"
#include "algorithms/segment/stand_removal.hpp"
#include "algorithms/upsample/upsample_view.hpp"
#include "io/capture_folder.hpp"
#include "pipeline/fill_stage.hpp"
#include "pipeline/stages.hpp"
#include "toolkit/mesh.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"

namespace rgbd::pipeline {

/// A frame of a capture to use as a view: (sensor id, position in its frame list).
using FrameRef = std::pair<std::string, std::size_t>;

/// The stages `ReconstructOptions::skip` can leave out, in the order they run.
const std::vector<std::string>& optional_stages();

/// The frames of frame set `frameset` (one per sensor that has one), or, for a capture without
/// frame sets, every frame of every sensor. Throws InputError when the frame set is out of
/// range or names a frame its sensor does not list. (rgbd-reconstruct selects with
/// --frameset / --frames.)
std::vector<FrameRef> frameset_frames(const io::Capture& capture, std::size_t frameset = 0);

/// What the chain runs and with which options. Every stage's options default to the single
/// tool's defaults, so reconstruct() and the pipe of single tools give the same mesh.
struct ReconstructOptions {
    std::set<std::string> skip;  ///< stages left out: "distance", "upsample", "density", "fill"
    /// Sensor noise model of the distance and density cleaning; nullopt: the rig's sensors'
    /// model when they all share one the denoisers know, else Kinect v2.
    std::optional<denoise::NoiseModel> noise_model;
    frames::CloudOptions cloud;
    SubjectStageOptions extraction;     ///< the object extraction after the clouds
    denoise::DistanceOptions distance;  ///< noise_model is set from `noise_model`
    upsample::UpsampleOptions upsample;
    registration::MultiViewOptions align;
    denoise::DensityOptions density;  ///< noise_model is set from `noise_model`
    /// The stand (turntable platter) below the object, removed after the alignment:
    /// auto = on single-sensor captures of several views (turntable), remove = always,
    /// keep = never (stand_stage in stages.hpp; algorithms/segment/stand_removal.hpp).
    using Stand = StandMode;
    Stand stand = Stand::kAuto;
    segment::StandOptions stand_options;
    FillStageOptions fill;
    reconstruction::ReconstructionOptions mesh;  ///< default: watertight as rgbd-mesh --watertight
    std::uint64_t seed = 0;                      ///< density cleaning's sampling seed

    ReconstructOptions() { mesh.watertight = true; }
    /// Throws InputError for an unknown stage in `skip` or invalid stage options.
    void check() const;
};

/// One row of the stages table: what ran, how long (wall-clock seconds), points in and out,
/// and stage-specific counts (views, points_added, faces).
struct StageRow {
    std::string stage;
    double time_s = 0;
    std::size_t points_in = 0;
    std::size_t points_out = 0;
    Report extra = Report::object();
};

/// What reconstruct() returns.
struct ReconstructResult {
    Mesh mesh;
    std::vector<StageRow> stages;  ///< in the order they ran
    /// Per-stage reports: noise_model, views (per view: counts, distance, upsample), align,
    /// density, fill, mesh, mesh_quality, counts.
    Report report;
    /// The aligned views without their points (view info and poses), for pose evaluation.
    std::vector<PointCloud> poses;
    /// The aligned points (with the filled ones) that were meshed, for pictures.
    render::Geometry input;
    /// The points the object extraction removed (world frame of the initial poses, at most
    /// 200,000), for the report's picture.
    std::vector<Eigen::Vector3d> removed;

    /// The stages as a JSON array of {stage, time_s, points_in, points_out, ...}.
    Report stages_report() const;
    /// {stage: time_s}, derived from `stages`.
    Report timings() const;
};

/// Callbacks for a front end: progress per stage, messages, and the views after each stage.
/// Every member may be empty.
struct ReconstructHooks {
    /// Called when a long stage ("clouds", "align", "density", "fill", "mesh") starts; returns
    /// the Progress the stage reports to. `stage_end` is called when it ends.
    std::function<Progress(const std::string& stage)> stage_begin;
    std::function<void(const std::string& stage)> stage_end;
    std::function<void(const std::string& message)> warn;
    std::function<void(const std::string& message)> info;
    /// The views after stage number `index` (1 views, 2 align, 3 density, 4 fill), as the pipe
    /// would carry them between the single tools.
    std::function<void(int index, const std::string& stage, const std::vector<PointCloud>& views)>
        views_after;
    /// Work of the front end's that needs the result's `input` and `removed` but not the mesh
    /// (a report picture): run once beside the mesh stage's sequential step on a second thread
    /// (reconstruction::ReconstructionOptions::beside_surface), finished before the mesh stage
    /// returns; nothing writes the result meanwhile.
    std::function<void(const ReconstructResult& result)> beside_mesh;
};

/// Runs the chain on `frames` of `capture` and meshes the result. Throws InputError when a
/// view has fewer than 100 points after cleaning (naming the capture, view and sensor), and
/// whatever the stages throw.
ReconstructResult reconstruct(const io::Capture& capture, const std::vector<FrameRef>& frames,
                              const ReconstructOptions& options,
                              const ReconstructHooks& hooks = {});

}  // namespace rgbd::pipeline
