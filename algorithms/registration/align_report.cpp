// Reporting and checks of align_views (icp.hpp): verdict names, option checks, the JSON
// report, and applying an alignment to the views.
#include <cmath>
#include <string>

#include "algorithms/registration/icp.hpp"
#include "toolkit/enum_names.hpp"
#include "toolkit/error.hpp"

namespace rgbd::registration {

namespace {
constexpr EnumName<Verdict> kVerdictNames[] = {
    {Verdict::kPass, "PASS"}, {Verdict::kWarn, "WARN"}, {Verdict::kFail, "FAIL"}};

/// The fields a view (ViewAlignment) and a pair (PairAlignment) report alike: verdict and
/// reason, fit, and disagreement with the final poses.
template <typename Alignment>
Report fit_report(const Alignment& a) {
    Report j;
    j["verdict"] = to_string(a.verdict);
    if (!a.reason.empty()) j["reason"] = a.reason;
    j["fitness"] = a.fitness;
    j["inlier_rmse_m"] = a.inlier_rmse;
    j["ring_rotation_deg"] = a.ring_rotation_deg;
    j["ring_translation_m"] = a.ring_translation_m;
    return j;
}
}  // namespace

const char* to_string(Verdict verdict) { return name_of(kVerdictNames, verdict); }

void MultiViewOptions::check() const {
    icp.check();
    RGBD_CHECK(std::isfinite(voxel_m) && voxel_m >= 0, "align_views: voxel_m must be >= 0");
    check_range("align_views: voxel_factor", voxel_factor, Range::open_closed(0, 100));
    check_range("align_views: normal_k", normal_k, Range::closed(3, 1024));
    RGBD_CHECK(max_points_per_view == 0 || max_points_per_view >= 100,
               "align_views: max_points_per_view must be 0 (no bound) or at least 100");
    RGBD_CHECK(std::isfinite(min_motion_spacing) && min_motion_spacing >= 0,
               "align_views: min_motion_spacing must be >= 0");
    check_range("align_views: min_fit_gain", min_fit_gain, Range::closed_open(0, 1));
    check_range("align_views: rounds", rounds, Range::closed(1, 1000));
    check_range("align_views: fail_fitness", fail_fitness, Range::closed(0, 1));
    check_range("align_views: warn_fitness", warn_fitness, Range::closed(0, 1));
    RGBD_CHECK(std::isfinite(calibration_prior_rotation_deg) &&
                   std::isfinite(calibration_prior_translation_m) &&
                   calibration_prior_rotation_deg >= 0 && calibration_prior_translation_m >= 0 &&
                   (calibration_prior_rotation_deg > 0) == (calibration_prior_translation_m > 0),
               "align_views: the calibration prior's rotation and translation must both be "
               "positive, or both 0 (off)");
    RGBD_CHECK(max_rotation_deg > 0 && max_translation_m > 0,
               "align_views: pose-change limits must be positive");
    check_range("align_views: pair_neighbours", pair_neighbours, Range::closed(1, 64));
    check_range("align_views: max_pair_angle_deg", max_pair_angle_deg, Range::open_closed(0, 180));
    check_range("align_views: feature_voxel_factor", feature_voxel_factor, Range::closed(1, 100));
    check_range("align_views: feature_radius_factor", feature_radius_factor, Range::closed(1, 100));
    check_range("align_views: ransac_iterations", ransac_iterations, Range::closed(1, 10000000));
    RGBD_CHECK(max_prior_rotation_deg > 0, "align_views: max_prior_rotation_deg must be > 0");
    RGBD_CHECK(std::isfinite(max_prior_translation_m) && max_prior_translation_m > 0,
               "align_views: max_prior_translation_m must be > 0");
    check_range("align_views: global_min_gain", global_min_gain, Range::closed(0, 1));
    check_range("align_views: colour_weight", colour_weight, Range::closed(0, 100));
    check_range("align_views: colour_sigma", colour_sigma, Range::open_closed(0, 1));
    check_range("align_views: pair_fail_fitness", pair_fail_fitness, Range::closed(0, 1));
    check_range("align_views: pair_warn_fitness", pair_warn_fitness, Range::closed(0, 1));
    RGBD_CHECK(prune_rotation_deg > 0 && prune_translation_spacing > 0,
               "align_views: prune thresholds must be positive");
}

Report MultiViewResult::to_json() const {
    Report r;
    r["verdict"] = to_string(verdict);
    r["spacing_m"] = spacing_m;
    r["voxel_m"] = voxel_m;
    r["max_distances_m"] = max_distances_m;
    r["iterations"] = iterations;
    r["time_s"] = time_s;
    r["views"] = Report::array();
    for (const ViewAlignment& v : views) {
        Report j = fit_report(v);
        j["view"] = v.view_id;
        j["world_from_sensor"] = pose_to_3x4(v.world_from_sensor);
        j["correction"] = pose_to_3x4(v.correction);
        j["iterations"] = v.iterations;
        j["converged"] = v.converged;
        j["rotation_change_deg"] = v.rotation_change_deg;
        j["translation_change_m"] = v.translation_change_m;
        j["pairs"] = v.pairs;
        r["views"].push_back(j);
    }
    r["times_s"] = {{"working_copies", working_time_s},
                    {"pairwise", pairwise_time_s},
                    {"safety_net", safety_net_time_s},
                    {"joint", joint_time_s}};
    r["start"] = start;
    r["pairwise_fitness"] = pairwise_fitness;
    r["joint_only_fitness"] = joint_only_fitness;
    if (held.ran)
        r["calibration_prior"] = {{"views_far_free", held.views_far_free},
                                  {"views_far_held", held.views_far_held},
                                  {"free_fitness", held.free_fitness},
                                  {"held_fitness", held.held_fitness},
                                  {"kept", held.kept}};
    r["pairs"] = Report::array();
    for (const PairAlignment& p : pairs) {
        Report j = fit_report(p);
        j["target"] = p.target;
        j["source"] = p.source;
        j["method"] = p.method;
        j["target_from_source"] = pose_to_3x4(p.target_from_source);
        j["colour_rmse"] = p.colour_rmse;
        j["ransac_inliers"] = p.ransac_inliers;
        j["global_tried"] = p.global_tried;
        j["candidates"] = p.candidates;
        j["in_graph"] = p.in_graph;
        r["pairs"].push_back(j);
    }
    if (loop.found) {
        Report l;
        l["order"] = loop.order;
        l["before_rotation_deg"] = loop.before_rotation_deg;
        l["before_translation_m"] = loop.before_translation_m;
        l["after_rotation_deg"] = loop.after_rotation_deg;
        l["after_translation_m"] = loop.after_translation_m;
        r["loop_closure"] = l;
    }
    return r;
}

void apply_alignment(std::vector<PointCloud>& views, const MultiViewResult& result) {
    RGBD_CHECK(views.size() == result.views.size(),
               "apply_alignment: " + std::to_string(views.size()) + " views but " +
                   std::to_string(result.views.size()) + " results");
    for (std::size_t v = 0; v < views.size(); ++v) {
        PointCloud& view = views[v];
        const ViewAlignment& va = result.views[v];
        if (view.view.frame == ViewFrame::kSensor) {
            view.view.world_from_sensor = va.world_from_sensor;
            to_world_frame(view);
        } else {
            transform(view, va.correction);
            if (view.view.world_from_sensor) view.view.world_from_sensor = va.world_from_sensor;
        }
    }
}

}  // namespace rgbd::registration
