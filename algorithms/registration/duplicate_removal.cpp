// Colour-based duplicate removal (see duplicate_removal.hpp).
#include "algorithms/registration/duplicate_removal.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <string>

#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/sampling/merge_views.hpp"
#include "algorithms/sampling/robust_spacing.hpp"
#include "toolkit/error.hpp"

namespace rgbd::registration {

namespace {

constexpr std::size_t kChunk = 1024;

std::array<double, 3> to_lab(Rgb c) {
    auto lin = [](std::uint8_t v) {
        const double s = v / 255.0;
        return s <= 0.04045 ? s / 12.92 : std::pow((s + 0.055) / 1.055, 2.4);
    };
    const double r = lin(c.r), g = lin(c.g), b = lin(c.b);
    const double x = (0.4124 * r + 0.3576 * g + 0.1805 * b) / 0.95047;
    const double y = 0.2126 * r + 0.7152 * g + 0.0722 * b;
    const double z = (0.0193 * r + 0.1192 * g + 0.9505 * b) / 1.08883;
    auto f = [](double t) {
        return t > 216.0 / 24389.0 ? std::cbrt(t) : (24389.0 / 27.0 * t + 16.0) / 116.0;
    };
    const double fx = f(x), fy = f(y), fz = f(z);
    return {116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)};
}

/// What happens to one point of the view being added.
enum class Action : std::uint8_t { kAdd, kDuplicate, kReplace, kWorse };

}  // namespace

void DuplicateOptions::check() const {
    check_range("duplicate removal: radius_spacing", radius_spacing, Range::open_closed(0, 100));
    RGBD_CHECK(std::isfinite(max_delta_e) && max_delta_e >= 0,
               "duplicate removal: max_delta_e must be >= 0");
    RGBD_CHECK(std::isfinite(spacing_m) && spacing_m >= 0,
               "duplicate removal: spacing_m must be >= 0");
}

Report DuplicateReport::to_json() const {
    return Report{{"input", input},
                  {"duplicates", duplicates},
                  {"replaced", replaced},
                  {"output", output},
                  {"radius_m", radius_m}};
}

double delta_e76(Rgb a, Rgb b) {
    const auto la = to_lab(a), lb = to_lab(b);
    return std::sqrt((la[0] - lb[0]) * (la[0] - lb[0]) + (la[1] - lb[1]) * (la[1] - lb[1]) +
                     (la[2] - lb[2]) * (la[2] - lb[2]));
}

PointCloud merge_without_duplicates(std::vector<PointCloud>&& views,
                                    const DuplicateOptions& options, DuplicateReport* report,
                                    const Progress& progress) {
    options.check();
    const std::size_t nv = views.size();
    RGBD_CHECK(nv >= 1, "duplicate removal: no views");
    // Flattened points, owners, expected noise and Lab colour.
    std::vector<std::size_t> offset(nv + 1, 0);
    for (std::size_t v = 0; v < nv; ++v) {
        RGBD_CHECK(views[v].view.frame == ViewFrame::kWorld,
                   "duplicate removal: view " + std::to_string(views[v].view.id) +
                       " is in its sensor frame; align and apply the poses first");
        offset[v + 1] = offset[v] + views[v].size();
    }
    const std::size_t total = offset[nv];
    std::vector<Eigen::Vector3d> xyz(total);
    std::vector<double> sigma(total, 0.0);
    std::vector<std::array<float, 3>> lab(total, {0, 0, 0});
    std::vector<std::uint32_t> owner(total);
    bool colours = true;
    for (const PointCloud& v : views) colours = colours && (v.empty() || v.has_colors());
    for (std::size_t v = 0; v < nv; ++v) {
        const PointCloud& view = views[v];
        const bool normals = view.points.has_normal_map();
        const std::optional<Pose> pose = view.view.world_from_sensor;
        const Pose sensor_from_world = pose ? pose->inverse() : Pose::Identity();
        std::optional<PointCloud::ColorMaps> cm;
        if (colours && !view.empty()) cm = view.colors();
        std::size_t i = offset[v];
        for (auto idx : view.points) {
            const Eigen::Vector3d p = to_eigen(view.points.point(idx));
            RGBD_CHECK(p.allFinite(), "duplicate removal: view " + std::to_string(view.view.id) +
                                          " has a non-finite point");
            xyz[i] = p;
            owner[i] = static_cast<std::uint32_t>(v);
            const Eigen::Vector3d ps = sensor_from_world * p;
            double theta = 0.0;
            if (normals && pose) {
                const Eigen::Vector3d n = to_eigen(view.points.normal(idx));
                const Eigen::Vector3d ray = pose->translation() - p;
                const double len = n.norm() * ray.norm();
                if (len > 0) theta = std::acos(std::min(1.0, std::abs(n.dot(ray)) / len));
            }
            sigma[i] = denoise::sigma_z_m(options.noise_model, std::max(ps.norm(), 1e-3), theta);
            if (cm) {
                const auto l = to_lab(cm->get(idx));
                lab[i] = {float(l[0]), float(l[1]), float(l[2])};
            }
            ++i;
        }
    }
    double spacing = options.spacing_m;
    if (spacing <= 0) {
        std::vector<const PointCloud*> all;
        for (const PointCloud& v : views) all.push_back(&v);
        spacing = sampling::median_view_spacing(all, 2000);
    }
    const double radius = options.radius_spacing * spacing;
    DuplicateReport rep;
    rep.input = total;
    rep.radius_m = radius;

    std::vector<char> alive(total, 1);
    if (radius > 0 && nv > 1) {
        const internal::KdTree tree(xyz);
        const double max_de2 = options.max_delta_e * options.max_delta_e;
        std::vector<Action> action(total, Action::kAdd);
        std::vector<std::pair<std::uint32_t, double>> nb_apply;
        auto de2_of = [&](std::size_t i, std::size_t j) {
            double d = 0;
            for (int k = 0; k < 3; ++k) d += (lab[i][k] - lab[j][k]) * (lab[i][k] - lab[j][k]);
            return d;
        };
        for (std::size_t v = 1; v < nv; ++v) {
            const std::size_t begin = offset[v], end = offset[v + 1];
            tbb::parallel_for(std::size_t{0}, (end - begin + kChunk - 1) / kChunk,
                              [&](std::size_t c) {
                                  std::vector<std::pair<std::uint32_t, double>> nb;
                                  const std::size_t stop = std::min(end, begin + (c + 1) * kChunk);
                                  for (std::size_t i = begin + c * kChunk; i < stop; ++i) {
                                      tree.radius(xyz[i], radius, nb);
                                      // Earlier live points within r: any of the same colour makes
                                      // i a duplicate; else i must be better observed than all of
                                      // them to replace them (so no differently coloured shell
                                      // stays near it).
                                      bool any = false, same = false, best = true;
                                      for (const auto& [j, d2] : nb) {
                                          if (owner[j] >= v || !alive[j]) continue;
                                          any = true;
                                          if (!colours || de2_of(i, j) <= max_de2) {
                                              same = true;
                                              break;
                                          }
                                          best = best && sigma[i] < sigma[j];
                                      }
                                      action[i] = !any   ? Action::kAdd
                                                  : same ? Action::kDuplicate
                                                  : best ? Action::kReplace
                                                         : Action::kWorse;
                                  }
                              });
            for (std::size_t i = begin; i < end; ++i) {
                switch (action[i]) {
                    case Action::kAdd:
                        break;
                    case Action::kDuplicate:
                        alive[i] = 0;
                        ++rep.duplicates;
                        break;
                    case Action::kWorse:
                        alive[i] = 0;
                        ++rep.replaced;
                        break;
                    case Action::kReplace:
                        tree.radius(xyz[i], radius, nb_apply);
                        for (const auto& [j, d2] : nb_apply)
                            if (owner[j] < v && alive[j] && de2_of(i, j) > max_de2) {
                                alive[j] = 0;
                                ++rep.replaced;
                            }
                        break;
                }
            }
            if (!report_progress(progress, double(v) / double(nv)))
                throw AlgorithmError("duplicate removal: cancelled");
        }
    }
    for (std::size_t v = 0; v < nv; ++v) {
        PointCloud& view = views[v];
        std::size_t i = offset[v];
        std::vector<PointSet::Index> drop;
        for (auto idx : view.points) {
            if (!alive[i]) drop.push_back(idx);
            ++i;
        }
        for (auto it = drop.rbegin(); it != drop.rend(); ++it) view.points.remove(*it);
        view.points.collect_garbage();
    }
    PointCloud merged = sampling::merge_views(std::move(views));
    rep.output = merged.size();
    if (report) *report = rep;
    report_progress(progress, 1.0);
    return merged;
}

}  // namespace rgbd::registration
