#include "algorithms/evaluation/observed.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "algorithms/evaluation/metrics.hpp"
#include "algorithms/segment/stand_removal.hpp"
#include "toolkit/error.hpp"
#include "toolkit/order_statistics.hpp"

namespace rgbd::evaluation {

namespace {

/// The pose that brings a view's points into the world frame (identity for world-frame views
/// and sensor-frame views without a pose).
Pose world_from_points(const PointCloud& view) {
    if (view.view.frame == ViewFrame::kSensor && view.view.world_from_sensor)
        return *view.view.world_from_sensor;
    return Pose::Identity();
}

/// Keeps the points of `view` for which keep(world point, index) holds; returns how many went.
template <typename Keep>
std::size_t keep_points(PointCloud& view, Keep keep) {
    const Pose pose = world_from_points(view);
    const auto first_removed =
        std::stable_partition(view.points.begin(), view.points.end(), [&](PointSet::Index i) {
            return keep(Eigen::Vector3d(pose * to_eigen(view.points.point(i))), i);
        });
    const auto removed = static_cast<std::size_t>(std::distance(first_removed, view.points.end()));
    if (removed > 0) {
        view.points.remove(first_removed, view.points.end());
        view.points.collect_garbage();
    }
    return removed;
}

std::size_t count_points(const std::vector<PointCloud>& views) {
    std::size_t n = 0;
    for (const auto& v : views) n += v.size();
    return n;
}

Report vector_json(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

/// "20mm", "0p5mm" (as metrics.hpp's keys).
std::string tau_key(double tau_m) {
    const double mm = std::round(tau_m * 1e6) / 1e3;
    char buffer[64];
    std::snprintf(buffer, sizeof buffer, "%gmm", mm);
    for (char* c = buffer; *c; ++c)
        if (*c == '.') *c = 'p';
    return buffer;
}

Report scores_json(const ObservedScores& s, double factor) {
    Report j = Report::object();
    j["tau_mm"] = s.tau_m * 1000.0;
    j["explained"] = s.explained;
    j["explained_points"] = s.explained_points;
    j["covered"] = s.covered;
    j["covered_area_m2"] = s.covered_area_m2;
    j["unsupported_area_fraction"] = s.unsupported_area_fraction;
    j["unsupported_area_m2"] = s.unsupported_area_m2;
    j["unsupported_beyond_mm"] = factor * s.tau_m * 1000.0;
    return j;
}

}  // namespace

void SubjectOptions::check() const {
    check_range("observed subject: radius", radius_m, Range::open_closed(0, 1e3), "m");
    check_range("observed subject: ground tilt", max_tilt_deg, Range::open(0, 90), "deg");
    check_range("observed subject: ground inlier distance", ground_inlier_m, Range::open(0, 1),
                "m");
    check_range("observed subject: ground margin", ground_margin_m, Range::closed_open(0, 1), "m");
    check_range("observed subject: ground support", ground_min_support, Range::open(0, 1));
}

Report observed_subject(std::vector<PointCloud>& views, const std::vector<cv::Mat>& labels,
                        const std::optional<Eigen::Vector3d>& centre,
                        const SubjectOptions& options) {
    options.check();
    Report report = Report::object();
    report["points_in"] = count_points(views);
    if (!labels.empty()) {
        RGBD_CHECK(labels.size() == views.size(),
                   "observed subject: " + std::to_string(labels.size()) + " label images for " +
                       std::to_string(views.size()) + " views");
        for (std::size_t v = 0; v < views.size(); ++v) {
            PointCloud& view = views[v];
            const cv::Mat& label = labels[v];
            const std::string what = "observed subject: view " + std::to_string(view.view.id);
            RGBD_CHECK(label.type() == CV_8UC1, what + ": label image is not 8-bit, one channel");
            if (view.empty()) continue;
            const auto pixel = view.pixel_map();
            RGBD_CHECK(pixel.has_value(), what + " has no pixel property to look its labels up");
            const std::size_t cells = static_cast<std::size_t>(label.rows) * label.cols;
            keep_points(view, [&](const Eigen::Vector3d&, PointSet::Index i) {
                const std::uint32_t p = (*pixel)[i];
                RGBD_CHECK(p < cells,
                           what + ": pixel " + std::to_string(p) + " lies outside its label image");
                return label.data[p] == kLabelSubject;
            });
        }
        report["selection"] = "labels";
        report["points"] = count_points(views);
        return report;
    }
    const auto up = segment::cameras_up(views);
    if (centre && up) {
        const double r2 = options.radius_m * options.radius_m;
        for (auto& view : views)
            keep_points(view, [&](const Eigen::Vector3d& p, PointSet::Index) {
                const Eigen::Vector3d d = p - *centre;
                return (d - d.dot(*up) * *up).squaredNorm() <= r2;
            });
        report["selection"] = "cylinder";
        report["radius_m"] = options.radius_m;
        report["centre"] = vector_json(*centre);
    } else {
        report["selection"] = "all";
        report["note"] = centre ? "no view has a pose to tell the up: every point kept"
                                : "the poses tell no centre where the sensors' axes converge: "
                                  "every point kept";
    }
    Report ground = Report::object();
    ground["found"] = false;
    if (up) report["up"] = vector_json(*up);
    if (!options.remove_ground) ground["skipped"] = "the views are cut to the subject by masks";
    if (up && options.remove_ground) {
        segment::StandOptions plane_options;
        plane_options.max_tilt_deg = options.max_tilt_deg;
        plane_options.inlier_m = options.ground_inlier_m;
        plane_options.margin_m = options.ground_margin_m;
        plane_options.min_support = options.ground_min_support;
        if (const auto plane = segment::find_support_plane(views, *up, plane_options)) {
            std::size_t removed = 0;
            for (auto& view : views)
                removed += keep_points(view, [&](const Eigen::Vector3d& p, PointSet::Index) {
                    return plane->normal.dot(p) + plane->offset >= options.ground_margin_m;
                });
            ground["found"] = true;
            ground["normal"] = vector_json(plane->normal);
            ground["offset_m"] = plane->offset;
            ground["inliers"] = plane->inliers;
            ground["tilt_deg"] =
                std::acos(std::clamp(plane->normal.dot(*up), -1.0, 1.0)) * 180.0 / M_PI;
            ground["removed"] = removed;
        }
    }
    report["ground"] = ground;
    report["points"] = count_points(views);
    return report;
}

void ObservedOptions::check() const {
    RGBD_CHECK(!taus_m.empty(), "observed metrics: at least one threshold tau is needed");
    for (double t : taus_m)
        RGBD_CHECK(std::isfinite(t) && t > 0.0,
                   "observed metrics: thresholds tau must be positive");
    check_range("observed metrics: unsupported factor", unsupported_factor, Range::closed(1, 1e3));
    check_range("observed metrics: samples", samples, Range::closed(1, 100000000));
}

ObservedMetrics observed_metrics(const Mesh& mesh, const std::vector<Eigen::Vector3d>& observed,
                                 const ObservedOptions& options) {
    options.check();
    const Stopwatch watch;
    RGBD_CHECK(mesh.number_of_faces() > 0, "observed metrics: the mesh has no faces");
    RGBD_CHECK(!observed.empty(), "observed metrics: no observed points");
    ObservedMetrics m;
    m.observed_points = observed.size();
    m.samples = options.samples;
    m.unsupported_factor = options.unsupported_factor;
    for (auto f : mesh.faces()) {
        std::vector<Eigen::Vector3d> c;
        for (auto v : CGAL::vertices_around_face(mesh.halfedge(f), mesh))
            c.push_back(to_eigen(mesh.point(v)));
        if (c.size() == 3) m.mesh_area_m2 += 0.5 * (c[1] - c[0]).cross(c[2] - c[0]).norm();
    }
    // Observations -> surface (exact), surface samples -> observations (nearest point).
    std::vector<double> to_mesh = distances_to_surface(observed, mesh);
    const std::vector<Eigen::Vector3d> samples =
        sample_surface(mesh, options.samples, options.seed);
    std::vector<double> to_observed = distances_to_points(samples, observed);
    const double per_sample = m.mesh_area_m2 / double(samples.size());
    for (double tau : options.taus_m) {
        ObservedScores s;
        s.tau_m = tau;
        for (double d : to_mesh) s.explained_points += d <= tau;
        s.explained = double(s.explained_points) / double(to_mesh.size());
        std::size_t covered = 0, unsupported = 0;
        for (double d : to_observed) {
            covered += d <= tau;
            unsupported += d > options.unsupported_factor * tau;
        }
        s.covered = double(covered) / double(samples.size());
        s.covered_area_m2 = double(covered) * per_sample;
        s.unsupported_area_fraction = double(unsupported) / double(samples.size());
        s.unsupported_area_m2 = double(unsupported) * per_sample;
        m.thresholds.push_back(s);
    }
    m.observed_to_mesh_median_m = lower_median(to_mesh);
    m.mesh_to_observed_median_m = lower_median(to_observed);
    m.time_s = watch.seconds();
    return m;
}

Report ObservedMetrics::to_json() const {
    Report j =
        thresholds.empty() ? Report::object() : scores_json(thresholds[0], unsupported_factor);
    j["mesh_area_m2"] = mesh_area_m2;
    j["observed_points"] = observed_points;
    j["samples"] = samples;
    j["observed_to_mesh_median_mm"] = observed_to_mesh_median_m * 1000.0;
    j["mesh_to_observed_median_mm"] = mesh_to_observed_median_m * 1000.0;
    for (std::size_t i = 1; i < thresholds.size(); ++i)
        j["at_" + tau_key(thresholds[i].tau_m)] = scores_json(thresholds[i], unsupported_factor);
    j["time_s"] = time_s;
    return j;
}

}  // namespace rgbd::evaluation
