// rgbd-eval --observed --baseline: Open3D 0.16's TSDF fusion and Screened Poisson
// (cli/peers/open3d_observed.py, Debian's python3-open3d) on the same observed subject points
// the result is judged on (pipeline/observed.hpp), so that the peers' meshes are scored by the
// same observed metrics beside ours.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "cli/common/tool.hpp"
#include "pipeline/observed.hpp"
#include "toolkit/mesh.hpp"
#include "toolkit/report.hpp"

namespace rgbd::cli {

/// A peer script of rgbd-eval (`name` in cli/peers/): beside the executable (copied there at
/// build time), else in the source tree this binary was built from. IoError when neither has it.
std::filesystem::path find_peer_script(const std::string& name);

/// `s` quoted for /bin/sh (single quotes, embedded ones escaped).
std::string shell_quote(const std::string& s);

/// Settings of the observed peers.
struct ObservedPeerOptions {
    double tsdf_voxel_m = 0.006;         ///< TSDF voxel size, m
    double tsdf_trunc_voxels = 4.0;      ///< TSDF truncation, voxels
    int poisson_depth = 9;               ///< Screened Poisson octree depth
    double poisson_trim_quantile = 0.0;  ///< drop Poisson vertices below this density quantile
};

/// One peer's mesh and its run: method, time_s (the peer's own timing), vertices, triangles.
struct ObservedBaseline {
    std::string name;  ///< "tsdf" or "screened_poisson"
    Mesh mesh;
    Report report;
};

/// The comma-separated peers of --baseline ("screened-poisson", "tsdf"), each once; tsdf
/// only with `observed`. UsageError otherwise.
std::vector<std::string> parse_baselines(const std::string& text, bool observed);

/// The observations of --observed CAPTURE: the frames --frameset / --frames select (depth
/// window --z-min / --z-max, masks), cut to the subject. InputError naming the folder when it
/// is missing or not a capture.
pipeline::Observations load_observed(const Context& ctx, const evaluation::SubjectOptions& subject);

/// Observed metrics of one mesh (evaluation::observed_metrics), or {"error": ...} for a mesh
/// without positive area.
Report observed_report(const Mesh& mesh, const std::vector<Eigen::Vector3d>& points,
                       const evaluation::ObservedOptions& options);

/// Estimates each view's normals (towards its camera) where missing, writes the views' points
/// (world frame) and cameras to a temporary folder, runs the peer once per method ("tsdf",
/// "screened-poisson"; a Poisson crash is retried on one thread), reads the meshes back and
/// removes the folder. Throws InputError without python3-open3d, AlgorithmError when a peer
/// fails.
std::vector<ObservedBaseline> run_observed_baselines(pipeline::Observations& observations,
                                                     const std::vector<std::string>& methods,
                                                     const ObservedPeerOptions& options,
                                                     const Context& ctx);

}  // namespace rgbd::cli
