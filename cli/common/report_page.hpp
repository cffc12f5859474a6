// The report folder of rgbd-eval --report and rgbd-reconstruct: one index.html with pictures
// (PNG files beside it), tables, and metrics.json, written into a temporary folder that then
// replaces DIR (no half-written report). And the standard pictures of a result: the input
// cloud, the result, a baseline, and error heat maps, all from one camera.
#pragma once

#include <filesystem>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "algorithms/render/picture.hpp"
#include "toolkit/mesh.hpp"
#include "toolkit/report.hpp"
#include "toolkit/textured_mesh.hpp"

namespace rgbd::cli {

/// One picture of a report page.
struct ReportImage {
    std::string file;     ///< file name inside the report folder, e.g. "result.png"
    std::string caption;  ///< shown under the picture
    cv::Mat image;        ///< CV_8UC3 BGR
};

/// A table: a header row and rows of cells (the first cell is the row name).
struct ReportTable {
    std::string heading;
    std::vector<std::string> columns;
    std::vector<std::vector<std::string>> rows;
};

/// What goes on the page.
struct ReportPage {
    std::string title;
    std::vector<std::pair<std::string, std::string>> facts;  ///< "label: value" lines on top
    std::vector<ReportImage> images;
    std::vector<ReportTable> tables;
    Report metrics;  ///< written as metrics.json and linked from the page
};

/// Writes DIR/index.html, DIR/metrics.json and the pictures. Everything is written into a
/// temporary sibling folder first, which then replaces DIR. Refuses (IoError) to replace an
/// existing DIR that is neither empty nor a report folder (no index.html).
void write_report(const std::filesystem::path& dir, const ReportPage& page);

/// HTML-escapes text.
std::string html_escape(const std::string& text);
/// A number with 4 significant digits; strings as they are; other JSON compactly.
std::string format_value(const Report& value);
/// Rows "key", value for every scalar leaf of `report` (nested keys joined with '.').
void flatten(const Report& report, const std::string& prefix,
             std::vector<std::pair<std::string, Report>>& out);
/// A table with one column per report (side by side): rows are the union of their flattened
/// scalar keys, in first-seen order; missing cells are empty.
ReportTable side_by_side(const std::string& heading,
                         const std::vector<std::pair<std::string, Report>>& columns);

/// The report pictures' view: oriented from the sensors (render::guess_orientation), the camera
/// fitted to a geometry's points (render::fit_camera).
struct PictureView {
    render::Orientation orientation;
    render::Camera camera;
};

/// The view fitted to `fit` (its points, or its mesh's vertices), oriented from `sensors`.
PictureView picture_view(const render::Geometry& fit, const std::vector<Pose>& sensors,
                         const render::CameraOptions& camera = {});

/// The input cloud's picture ("input.png") under `camera`.
ReportImage input_picture(const render::Geometry& input, const render::Camera& camera);

/// What to picture: any of these may be null.
struct PictureInputs {
    const render::Geometry* input = nullptr;  ///< the input cloud (world frame)
    const Mesh* result = nullptr;             ///< our result
    const TexturedMesh* textured = nullptr;   ///< the result textured (-o model.obj|glb)
    const Mesh* baseline = nullptr;           ///< a peer's result
    std::string baseline_name = "baseline";
    const Mesh* reference = nullptr;  ///< true surface: heat maps show distance to it, else
                                      ///< to the input points
    render::CameraOptions camera;     ///< size and direction (orientation from the input)
    /// A view and an input picture made beforehand (rgbd-reconstruct renders them beside the
    /// mesh stage, fitted to the input): used as they are, the picture moved from.
    const PictureView* view = nullptr;
    ReportImage* input_image = nullptr;
};

/// Renders the input, the result (and, when given, the textured result and its close-up,
/// same cameras), the baseline and the heat maps of the result's and the
/// baseline's per-vertex distance (to the reference, else to the input points; one colour
/// range for both, in mm) with one camera fitted to the result (else the input; or the
/// given view, with the given input picture). Appends to
/// `images` and returns a short description of the heat maps' distance ("to the reference").
std::string render_report_pictures(const PictureInputs& inputs, std::vector<ReportImage>& images,
                                   Report& info);

/// The object extraction's picture: the kept points in their colours and the removed ones
/// (world frame) in a neutral grey, seen from the sensors' side as the other pictures.
/// Returns an image with an empty file name when there is nothing to draw.
ReportImage extraction_picture(const render::Geometry& kept,
                               const std::vector<Eigen::Vector3d>& removed,
                               const render::CameraOptions& camera = {});

}  // namespace rgbd::cli
