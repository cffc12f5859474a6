// The stages of the method as library calls, shared by the single-stage tools, rgbd-reconstruct
// (through pipeline::reconstruct) and the examples, so that a chain of pipes and the
// one-command run compute the same thing: views from frames, alignment with per-view normals,
// meshing of a set of views, and evaluation against ground truth (docs/method.md).
#pragma once

#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "algorithms/denoise/sensor_noise.hpp"
#include "algorithms/evaluation/metrics.hpp"
#include "algorithms/frames/depth_to_cloud.hpp"
#include "algorithms/reconstruction/reconstruct_surface.hpp"
#include "algorithms/registration/icp.hpp"
#include "algorithms/segment/stand_removal.hpp"
#include "algorithms/segment/subject_extraction.hpp"
#include "io/capture_folder.hpp"
#include "toolkit/mesh.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"

namespace rgbd::pipeline {

/// The per-view crop of the live paths (3D video, rgbd-capture --live, rgbd-calibrate --refine),
/// which see one view at a time: a ball around where the sensors' axes converge.
struct ExtractionOptions {
    double crop_radius_m = 0.6;  ///< 0 = no world-space crop
};

/// The object extraction of rgbd-cloud and rgbd-reconstruct, over all views of a frame set
/// (segment::extract_subject): the ground removed, the subject kept, its extent from the data.
struct SubjectStageOptions {
    bool enabled = true;  ///< false: every point in the depth window is kept (--no-extract)
    /// > 0: a ball of this radius around where the sensors' axes converge decides the extent
    /// instead of the regions (the override; the ground is still removed), metres.
    double crop_radius_m = 0.0;
    segment::SubjectOptions subject;  ///< remove_ground false: --keep-ground
    /// Throws InputError for invalid values.
    void check() const;
};

/// Runs the object extraction on the views of one frame set (sensor frames, initial poses):
/// the crop when `options.crop_radius_m` > 0 and `centre` is known, then
/// segment::extract_subject with each view's noise model (view_noise_model, else the stream's);
/// last, also when the stage is off, colour_hidden_points() on what is left.
/// Returns its report, with "crop" when the crop ran; null when the stage is off.
/// `removed_world`, when given, receives the removed points in the world frame (at most 200,000,
/// evenly strided) for the report's picture.
Report extract_stage(std::vector<PointCloud>& views, const std::optional<Eigen::Vector3d>& centre,
                     const SubjectStageOptions& options, const Progress& progress = {},
                     std::vector<Eigen::Vector3d>* removed_world = nullptr);

/// The object centre of a selection of frames: where the optical axes of their (initial)
/// poses converge, or nullopt when the poses do not tell (one view, parallel axes, no poses).
std::optional<Eigen::Vector3d> object_centre(
    const io::Capture& capture, const std::vector<std::pair<std::string, std::size_t>>& jobs);
/// The same for the rig's sensor poses (nullopt when a sensor has none).
std::optional<Eigen::Vector3d> object_centre(const io::Rig& rig);

/// One frame as a view: depth_to_cloud, then the world-space crop around `centre` when given.
/// Fills view.id and view.frame_index, and writes the frame's noise model (frame_noise_model)
/// into the view's metadata (`rgbd:sensor.noise_model NAME`, nothing when it is unknown), so
/// that the denoisers down a pipe know it; the report gets the counts. rgbd-cloud (through
/// load_view), rgbd-capture's live stream and pipeline::reconstruct make their views here.
PointCloud view_from_frame(const RgbdFrame& frame, int view_id,
                           const frames::CloudOptions& cloud_options,
                           const std::optional<Eigen::Vector3d>& centre,
                           const ExtractionOptions& extraction, Report& report);

/// The points of the views that their colour cameras did not see, which view_from_frame leaves
/// grey (flagged uncoloured: depth_to_cloud without CloudOptions::colour_hidden), take the
/// colour of the nearest seen point of their view (frames::colour_uncoloured), views in
/// parallel. extract_stage does it last, on the subject's points only; a caller of
/// view_from_frame that does not run extract_stage calls it itself.
void colour_hidden_points(std::vector<PointCloud>& views);

/// The denoisers' noise model of the frame's sensor: its noise.model, else its model, when
/// the denoisers know the name; nullopt otherwise.
std::optional<denoise::NoiseModel> frame_noise_model(const RgbdFrame& frame);
/// The noise model a view's metadata names, else nullopt.
std::optional<denoise::NoiseModel> view_noise_model(const PointCloud& view);
/// The noise model the denoisers use on views whose model is not given (rgbd-clean
/// --noise-model auto, rgbd-reconstruct --noise-model auto): the one every view names when
/// they agree, else Kinect v2. One view: its own.
denoise::NoiseModel stream_noise_model(const std::vector<PointCloud>& views);

/// Loads one selected frame of a capture as a view (io::load_frame, then view_from_frame).
PointCloud load_view(const io::Capture& capture, const std::string& sensor_id, std::size_t position,
                     int view_id, const frames::CloudOptions& cloud_options,
                     const std::optional<Eigen::Vector3d>& centre,
                     const ExtractionOptions& extraction, Report& report);

/// Registers views (sensor frame, initial pose in view.world_from_sensor) to each other:
/// estimates normals oriented to the sensor where missing, refines the poses jointly, then
/// brings every view into the world frame with its refined pose. Returns the report with one
/// entry per view (verdict, fitness, RMSE, pose change).
Report align_stage(std::vector<PointCloud>& views, const registration::MultiViewOptions& options,
                   const Progress& progress = {});

/// The stand (turntable platter) below the object, after the alignment: auto = on streams of
/// three or more views of one sensor (a turntable), remove = always, keep = never.
enum class StandMode { kAuto, kRemove, kKeep };
/// "auto", "remove" or "keep"; InputError naming the valid ones otherwise.
StandMode parse_stand_mode(const std::string& name);

/// Whether the stand stage runs on these views in this mode.
bool stand_applies(const std::vector<PointCloud>& views, StandMode mode);

/// The stand stage of rgbd-align and rgbd-reconstruct (algorithms/segment/stand_removal.hpp):
/// when `mode` says so, removes the stand from the aligned views and writes its plane into
/// every view's metadata (`rgbd:stand.plane nx ny nz offset_m`), so that the mesh stage,
/// in the same process or at the end of a pipe, carries the object's walls down to it
/// (add_stand_contact). Returns remove_stand's report, or null when the stage did not run.
Report stand_stage(std::vector<PointCloud>& views, StandMode mode,
                   const segment::StandOptions& options, const Progress& progress = {});

/// The stand plane written by stand_stage into the views' metadata, if any view carries one.
/// InputError when the line does not hold four finite numbers with a unit normal.
std::optional<segment::SupportPlane> stand_plane_of(const std::vector<PointCloud>& views);

/// When the views carry a stand plane: appends segment::contact_points (the object's walls
/// carried down to the plane, flagged synthetic) as one more view, so the closed mesh's flat
/// base lies where the object stood. Returns the number of points added.
std::size_t add_stand_contact(std::vector<PointCloud>& views,
                              const segment::StandOptions& options = {});

/// Merges views (any frame; normals estimated per view towards its sensor when missing) and
/// reconstructs a coloured mesh.
Mesh mesh_stage(std::vector<PointCloud>&& views,
                const reconstruction::ReconstructionOptions& options, Report& report,
                const Progress& progress = {});

/// A result to evaluate: a mesh, or views.
struct LoadedResult {
    std::optional<Mesh> mesh;
    std::vector<PointCloud> views;
};
/// Reads a mesh (.ply stream with a mesh document, .off, .obj) or views (.ply stream, other
/// point formats).
LoadedResult load_result(const std::string& path);

/// Surface metrics of a result against a reference mesh.
Report evaluate_surface(const LoadedResult& result, const Mesh& reference,
                        const evaluation::MetricOptions& options);

/// True poses from gt/world_from_depth.json: keys "<sensor>" or, for per-frame poses,
/// "<sensor>/<index>". Throws InputError naming the file.
std::map<std::string, Pose> read_gt_poses(const std::string& path);

/// The sensor-level true poses of a capture: its gt/world_from_depth.json without the per-frame
/// "<sensor>/<index>" entries (a synthetic capture's truth, whose rig.json poses carry a
/// calibration error); empty when the capture has none. Throws InputError naming a malformed
/// file.
std::map<std::string, Pose> read_sensor_gt_poses(const io::Capture& capture);

/// Pose errors of the views' world_from_sensor against the truth.
Report evaluate_poses(const std::vector<PointCloud>& views, const std::string& gt_path,
                      bool remove_gauge);

}  // namespace rgbd::pipeline
