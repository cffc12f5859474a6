#include "cli/common/report_page.hpp"

#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <sstream>

#include "algorithms/evaluation/metrics.hpp"
#include "io/capture_folder.hpp"
#include "io/output_file.hpp"
#include "toolkit/error.hpp"
#include "toolkit/order_statistics.hpp"

namespace rgbd::cli {

namespace fs = std::filesystem;

std::string html_escape(const std::string& s) {
    std::string out;
    for (char c : s) {
        if (c == '<')
            out += "&lt;";
        else if (c == '>')
            out += "&gt;";
        else if (c == '&')
            out += "&amp;";
        else if (c == '"')
            out += "&quot;";
        else
            out += c;
    }
    return out;
}

std::string format_value(const Report& v) {
    if (v.is_number_float()) {
        std::ostringstream s;
        s.precision(4);
        s << v.get<double>();
        return s.str();
    }
    return v.is_string() ? v.get<std::string>() : v.dump();
}

void flatten(const Report& r, const std::string& prefix,
             std::vector<std::pair<std::string, Report>>& out) {
    if (!r.is_object()) {
        if (!r.is_array()) out.emplace_back(prefix, r);
        return;
    }
    for (auto it = r.begin(); it != r.end(); ++it) {
        const std::string key = prefix.empty() ? it.key() : prefix + "." + it.key();
        flatten(*it, key, out);
    }
}

ReportTable side_by_side(const std::string& heading,
                         const std::vector<std::pair<std::string, Report>>& columns) {
    ReportTable t;
    t.heading = heading;
    t.columns.push_back("");
    std::vector<std::string> keys;
    std::vector<std::vector<std::pair<std::string, Report>>> flat(columns.size());
    for (std::size_t c = 0; c < columns.size(); ++c) {
        t.columns.push_back(columns[c].first);
        flatten(columns[c].second, "", flat[c]);
        for (const auto& [k, v] : flat[c])
            if (std::find(keys.begin(), keys.end(), k) == keys.end()) keys.push_back(k);
    }
    for (const auto& k : keys) {
        std::vector<std::string> row{k};
        for (const auto& f : flat) {
            auto it =
                std::find_if(f.begin(), f.end(), [&](const auto& kv) { return kv.first == k; });
            row.push_back(it == f.end() ? std::string() : format_value(it->second));
        }
        t.rows.push_back(std::move(row));
    }
    return t;
}

namespace {

std::string page_html(const ReportPage& page) {
    std::ostringstream html;
    html << "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>"
         << html_escape(page.title)
         << "</title><style>body{font-family:sans-serif;margin:1em;background:#fff}"
            "table{border-collapse:collapse;margin-bottom:1em}"
            "td,th{border:1px solid #ccc;padding:2px 8px}td:not(:first-child){text-align:right}"
            ".pics{display:flex;flex-wrap:wrap;gap:12px}figure{margin:0}"
            "figure img{display:block;border:1px solid #ddd}"
            "figcaption{font-size:90%;color:#333}</style></head><body>\n<h1>"
         << html_escape(page.title) << "</h1>\n";
    if (!page.facts.empty()) {
        html << "<p>";
        for (std::size_t i = 0; i < page.facts.size(); ++i)
            html << (i ? "<br>" : "") << html_escape(page.facts[i].first) << ": "
                 << html_escape(page.facts[i].second);
        html << "</p>\n";
    }
    if (!page.images.empty()) {
        html << "<div class=\"pics\">\n";
        for (const auto& im : page.images)
            html << "<figure><img src=\"" << html_escape(im.file) << "\" width=\"" << im.image.cols
                 << "\" height=\"" << im.image.rows << "\" alt=\"" << html_escape(im.caption)
                 << "\"><figcaption>" << html_escape(im.caption) << "</figcaption></figure>\n";
        html << "</div>\n";
    }
    for (const auto& t : page.tables) {
        html << "<h2>" << html_escape(t.heading) << "</h2>\n<table>\n<tr>";
        for (const auto& c : t.columns) html << "<th>" << html_escape(c) << "</th>";
        html << "</tr>\n";
        for (const auto& row : t.rows) {
            html << "<tr>";
            for (const auto& cell : row) html << "<td>" << html_escape(cell) << "</td>";
            html << "</tr>\n";
        }
        html << "</table>\n";
    }
    html << "<p>Full numbers: <a href=\"metrics.json\">metrics.json</a></p>\n</body></html>\n";
    return html.str();
}

}  // namespace

void write_report(const fs::path& dir, const ReportPage& page) {
    io::FolderPolicy policy;
    policy.create_parent = true;
    policy.refuse = [](const fs::path& target) -> std::string {
        if (fs::is_empty(target) || fs::exists(target / "index.html")) return "";
        return "exists and is not a report folder (no index.html); not replacing it";
    };
    io::write_folder_atomic(
        dir,
        [&](const fs::path& folder) {
            // PNG encoding is sequential per image: the images side by side.
            tbb::parallel_for(std::size_t(0), page.images.size(), [&](std::size_t i) {
                io::write_image_atomic(folder / page.images[i].file, page.images[i].image);
            });
            io::write_text_atomic(folder / "metrics.json", page.metrics.dump(2) + "\n");
            io::write_text_atomic(folder / "index.html", page_html(page));
        },
        policy);
}

PictureView picture_view(const render::Geometry& fit, const std::vector<Pose>& sensors,
                         const render::CameraOptions& camera) {
    Eigen::Vector3d lo = fit.vertices.front(), hi = lo;
    for (const auto& v : fit.vertices) {
        lo = lo.cwiseMin(v);
        hi = hi.cwiseMax(v);
    }
    PictureView view;
    view.orientation = render::guess_orientation(sensors, 0.5 * (lo + hi), std::nullopt);
    view.camera = render::fit_camera(fit.vertices, view.orientation, camera);
    return view;
}

ReportImage input_picture(const render::Geometry& input, const render::Camera& camera) {
    return {"input.png", "input points (" + std::to_string(input.vertices.size()) + ")",
            render::render_picture(input, camera, {}).image};
}

std::string render_report_pictures(const PictureInputs& in, std::vector<ReportImage>& images,
                                   Report& info) {
    using render::Geometry;
    std::optional<Geometry> result, baseline;
    if (in.result) result = render::from_mesh(*in.result);
    if (in.baseline) baseline = render::from_mesh(*in.baseline);
    std::optional<Geometry> textured;
    if (in.textured) textured = render::from_textured_mesh(*in.textured);
    const Geometry* fit = result ? &*result : in.input;
    if (!fit) return {};
    const PictureView view =
        in.view ? *in.view
                : picture_view(*fit, in.input ? in.input->sensors : std::vector<Pose>{}, in.camera);
    const render::Orientation& orientation = view.orientation;
    const render::Camera& camera = view.camera;
    render::PictureOptions plain;
    std::string against;
    if (in.reference)
        against = "distance to the reference";
    else if (in.input)
        against = "distance to the input points";
    auto distances = [&](const Geometry& g) {
        if (in.reference) return evaluation::distances_to_surface(g.vertices, *in.reference);
        return evaluation::distances_to_points(g.vertices, in.input->vertices);
    };
    // The plain pictures and the heat maps' distances do not depend on each other: side by
    // side (each is parallel inside, but has sequential parts). Pictures keep their order.
    ReportImage input_image, result_image, textured_image, baseline_image;
    std::vector<double> result_distances, baseline_distances;
    tbb::parallel_invoke(
        [&] {
            if (in.input_image)
                input_image = std::move(*in.input_image);
            else if (in.input)
                input_image = input_picture(*in.input, camera);
        },
        [&] {
            if (result)
                result_image = {
                    "result.png",
                    "result (" + std::to_string(result->triangles.size()) + " triangles)",
                    render::render_picture(*result, camera, plain).image};
        },
        [&] {
            if (textured)
                textured_image = {"textured.png",
                                  "textured result (" +
                                      std::to_string(in.textured->atlases.size()) + " atlas, " +
                                      std::to_string(in.textured->faces.size()) + " triangles)",
                                  render::render_picture(*textured, camera, plain).image};
        },
        [&] {
            if (baseline)
                baseline_image = {"baseline.png",
                                  in.baseline_name + " (" +
                                      std::to_string(baseline->triangles.size()) + " triangles)",
                                  render::render_picture(*baseline, camera, plain).image};
        },
        [&] {
            if (against.empty()) return;
            if (result) result_distances = distances(*result);
            if (baseline) baseline_distances = distances(*baseline);
        });
    for (ReportImage* image : {&input_image, &result_image, &textured_image, &baseline_image})
        if (!image->file.empty()) images.push_back(std::move(*image));
    if (against.empty()) return {};

    // Heat maps: one range for both.
    auto p98 = [](std::vector<double> d) { return count_quantile(d, 0.98); };
    double vmax = 0;
    if (result) vmax = std::max(vmax, p98(result_distances));
    if (baseline) vmax = std::max(vmax, p98(baseline_distances));
    render::PictureOptions heat;
    heat.scalar_min = 0.0;
    heat.scalar_max = vmax > 0 ? vmax : 1e-3;
    heat.scalar_label = "mm";
    heat.scalar_display_scale = 1000.0;
    info["heat_map"] = {{"distance", against}, {"max_m", *heat.scalar_max}};
    // Close-ups of the result's top quarter along up (a head, a face: the fine detail users
    // judge), same colours and heat range, camera fitted to those vertices only. The colour
    // close-up draws the result without the distances (a geometry with scalars is drawn as a
    // heat map whatever the options); the others draw copies that carry them.
    std::optional<render::Camera> close;
    if (result && result->vertices.size() >= 100) {
        std::vector<double> heights;
        heights.reserve(result->vertices.size());
        for (const auto& v : result->vertices) heights.push_back(v.dot(orientation.up));
        std::vector<double> sorted = heights;
        const double top_quarter = rank_quantile(sorted, 0.75);
        std::vector<Eigen::Vector3d> top;
        for (std::size_t i = 0; i < heights.size(); ++i)
            if (heights[i] >= top_quarter) top.push_back(result->vertices[i]);
        close = render::fit_camera(top, orientation, in.camera);
    }
    std::optional<Geometry> result_heat, baseline_heat;
    if (result) {
        result_heat = *result;
        result_heat->scalars = std::move(result_distances);
    }
    if (baseline) {
        baseline_heat = std::move(*baseline);
        baseline_heat->scalars = std::move(baseline_distances);
    }
    ReportImage result_error, baseline_error, closeup, closeup_error, textured_closeup;
    tbb::parallel_invoke(
        [&] {
            if (result_heat)
                result_error = {"result_error.png", "result: " + against + " (mm)",
                                render::render_picture(*result_heat, camera, heat).image};
        },
        [&] {
            if (baseline_heat)
                baseline_error = {"baseline_error.png", in.baseline_name + ": " + against + " (mm)",
                                  render::render_picture(*baseline_heat, camera, heat).image};
        },
        [&] {
            if (close)
                closeup = {"result_closeup.png", "result, close-up of the top quarter",
                           render::render_picture(*result, *close, plain).image};
        },
        [&] {
            if (close)
                closeup_error = {"result_closeup_error.png",
                                 "result, close-up: " + against + " (mm)",
                                 render::render_picture(*result_heat, *close, heat).image};
        },
        [&] {
            if (close && textured)
                textured_closeup = {"textured_closeup.png", "textured result, close-up",
                                    render::render_picture(*textured, *close, plain).image};
        });
    for (ReportImage* image :
         {&result_error, &baseline_error, &closeup, &textured_closeup, &closeup_error})
        if (!image->file.empty()) images.push_back(std::move(*image));
    return against;
}

ReportImage extraction_picture(const render::Geometry& kept,
                               const std::vector<Eigen::Vector3d>& removed,
                               const render::CameraOptions& camera) {
    if (kept.vertices.empty() && removed.empty()) return {};
    render::Geometry all;
    all.sensors = kept.sensors;
    all.vertices = kept.vertices;
    const bool coloured = kept.colors.size() == kept.vertices.size();
    all.colors = coloured ? kept.colors : std::vector<Rgb>(kept.vertices.size(), Rgb{200, 60, 40});
    // Removed points: a neutral grey, lighter than most subjects.
    for (const auto& p : removed) {
        all.vertices.push_back(p);
        all.colors.push_back(Rgb{185, 185, 185});
    }
    Eigen::Vector3d lo = all.vertices.front(), hi = lo;
    for (const auto& v : all.vertices) lo = lo.cwiseMin(v), hi = hi.cwiseMax(v);
    const render::Orientation orientation =
        render::guess_orientation(all.sensors, 0.5 * (lo + hi), std::nullopt);
    const render::Camera cam = render::fit_camera(all.vertices, orientation, camera);
    return {"extraction.png",
            "object extraction: " + std::to_string(kept.vertices.size()) + " points kept, " +
                std::to_string(removed.size()) + " removed (grey)",
            render::render_picture(all, cam, {}).image};
}

}  // namespace rgbd::cli
