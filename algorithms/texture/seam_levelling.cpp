#include "algorithms/texture/seam_levelling.hpp"

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <set>

#include "algorithms/internal/ring_dilation.hpp"
#include "toolkit/error.hpp"

namespace rgbd::texture {
namespace {

/// The unknowns: one per (vertex, chart) pair of the charts' faces.
struct Unknowns {
    std::vector<std::vector<std::pair<int, int>>> of_vertex;  ///< vertex -> (chart, index)
    int count = 0;

    int index(int vertex, int chart) const {
        for (const auto& [c, i] : of_vertex[vertex])
            if (c == chart) return i;
        return -1;
    }
    int add(int vertex, int chart) {
        const int i = index(vertex, chart);
        if (i >= 0) return i;
        of_vertex[vertex].emplace_back(chart, count);
        return count++;
    }
};

}  // namespace

void LevellingOptions::check() const {
    RGBD_CHECK(std::isfinite(smoothness) && smoothness > 0 && smoothness <= 1e6,
               "texture: seam levelling smoothness must be in (0, 1e6]");
    RGBD_CHECK(std::isfinite(regularisation) && regularisation > 0 && regularisation <= 1e3,
               "texture: seam levelling regularisation must be in (0, 1000]");
    RGBD_CHECK(std::isfinite(outlier_levels) && outlier_levels > 0,
               "texture: seam levelling outlier threshold must be > 0");
}

SeamCorrections level_seams(const render::RenderScene& scene, const std::vector<TextureView>& views,
                            const std::vector<ColourGain>& gains, const std::vector<Chart>& charts,
                            const std::vector<std::array<int, 3>>& adjacency,
                            const LevellingOptions& options, Report& report) {
    options.check();
    Stopwatch watch;
    const auto& verts = scene.vertices();
    const auto& tris = scene.triangles();
    RGBD_CHECK(adjacency.size() == tris.size() && gains.size() == views.size(),
               "texture: seam levelling inputs disagree in size");
    SeamCorrections out;
    out.chart_vertex.resize(charts.size());
    report["enabled"] = options.enabled;
    if (!options.enabled || charts.size() < 2) {
        for (std::size_t c = 0; c < charts.size(); ++c)
            for (const int f : charts[c].faces)
                for (const int v : tris[f]) out.chart_vertex[c][v] = Eigen::Vector3f::Zero();
        return out;
    }
    std::vector<int> chart_of(tris.size(), -1);
    Unknowns unknowns;
    unknowns.of_vertex.resize(verts.size());
    for (std::size_t c = 0; c < charts.size(); ++c)
        for (const int f : charts[c].faces) {
            chart_of[f] = static_cast<int>(c);
            for (const int v : tris[f]) unknowns.add(v, static_cast<int>(c));
        }
    const int n = unknowns.count;
    std::vector<Pose> camera_from_world(views.size());
    for (std::size_t v = 0; v < views.size(); ++v)
        camera_from_world[v] = views[v].world_from_camera.inverse();
    // Colours along the seam edges: per unknown, the weighted sum of its chart's samples near
    // its vertex; per seam vertex, the chart pairs meeting there.
    std::vector<Eigen::Vector3d> colour_sum(n, Eigen::Vector3d::Zero());
    std::vector<double> weight_sum(n, 0.0);
    std::set<std::pair<int, int>> pair_terms;  // (unknown A, unknown B), A < B
    std::vector<Eigen::Triplet<double>> triplets;
    auto difference_term = [&](int i, int j, double w) {
        triplets.emplace_back(i, i, w);
        triplets.emplace_back(j, j, w);
        triplets.emplace_back(i, j, -w);
        triplets.emplace_back(j, i, -w);
    };
    std::size_t seam_edges = 0, interior_edges = 0;
    for (std::size_t f = 0; f < tris.size(); ++f) {
        const int a_chart = chart_of[f];
        if (a_chart < 0) continue;
        for (int j = 0; j < 3; ++j) {
            const int g = adjacency[f][j];
            const int va = tris[f][j], vb = tris[f][(j + 1) % 3];
            const int b_chart = g >= 0 ? chart_of[g] : -1;
            if (b_chart == a_chart) {
                if (g < static_cast<int>(f)) continue;  // each interior edge once
                difference_term(unknowns.index(va, a_chart), unknowns.index(vb, a_chart),
                                options.smoothness);
                ++interior_edges;
                continue;
            }
            // A border of chart A: the edge term within A, and a seam when B is a chart.
            difference_term(unknowns.index(va, a_chart), unknowns.index(vb, a_chart),
                            options.smoothness);
            if (b_chart < 0 || g < static_cast<int>(f)) continue;
            ++seam_edges;
            const int charts_ab[2] = {a_chart, b_chart};
            Eigen::Vector2d px[2][2];
            for (int s = 0; s < 2; ++s) {
                const int view = charts[charts_ab[s]].view;
                px[s][0] = views[view].intrinsics.project(camera_from_world[view] * verts[va]);
                px[s][1] = views[view].intrinsics.project(camera_from_world[view] * verts[vb]);
            }
            const double length_px =
                std::max((px[0][1] - px[0][0]).norm(), (px[1][1] - px[1][0]).norm());
            const int samples = std::clamp(static_cast<int>(std::ceil(length_px)), 2, 64);
            for (int s = 0; s < 2; ++s) {
                const int view = charts[charts_ab[s]].view;
                const int ia = unknowns.index(va, charts_ab[s]),
                          ib = unknowns.index(vb, charts_ab[s]);
                for (int k = 0; k < samples; ++k) {
                    const double t = (k + 0.5) / samples;
                    const Eigen::Vector2d p = (1 - t) * px[s][0] + t * px[s][1];
                    const Eigen::Vector3d colour =
                        adjusted(gains[view], sample_bgr(views[view].image, p.x(), p.y()));
                    colour_sum[ia] += (1 - t) * colour;
                    weight_sum[ia] += 1 - t;
                    colour_sum[ib] += t * colour;
                    weight_sum[ib] += t;
                }
            }
            for (const int v : {va, vb}) {
                const int i = unknowns.index(v, a_chart), k = unknowns.index(v, b_chart);
                pair_terms.insert(std::minmax(i, k));
            }
        }
    }
    // The seam terms: (f_i + g_i - f_j - g_j)^2, normal equations A g = b.
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(n, 3);
    std::size_t seam_terms = 0, outliers = 0;
    for (const auto& [i, j] : pair_terms) {
        if (!(weight_sum[i] > 0 && weight_sum[j] > 0)) continue;
        const Eigen::Vector3d d = colour_sum[i] / weight_sum[i] - colour_sum[j] / weight_sum[j];
        if (d.cwiseAbs().maxCoeff() > options.outlier_levels) {
            ++outliers;
            continue;
        }
        ++seam_terms;
        difference_term(i, j, 1.0);
        rhs.row(i) -= d.transpose();
        rhs.row(j) += d.transpose();
    }
    for (int i = 0; i < n; ++i) triplets.emplace_back(i, i, options.regularisation);
    Eigen::SparseMatrix<double> a(n, n);
    a.setFromTriplets(triplets.begin(), triplets.end());
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(a);
    RGBD_CHECK(solver.info() == Eigen::Success, "texture: seam levelling system not solvable");
    const Eigen::MatrixXd g = solver.solve(rhs);
    double sum_abs = 0, max_abs = 0;
    for (std::size_t v = 0; v < verts.size(); ++v)
        for (const auto& [c, i] : unknowns.of_vertex[v]) {
            out.chart_vertex[c][static_cast<int>(v)] = g.row(i).transpose().cast<float>();
            sum_abs += g.row(i).cwiseAbs().mean();
            max_abs = std::max(max_abs, g.row(i).cwiseAbs().maxCoeff());
        }
    report["unknowns"] = n;
    report["seam_edges"] = seam_edges;
    report["interior_edges"] = interior_edges;
    report["seam_terms"] = seam_terms;
    report["seam_outliers"] = outliers;
    report["mean_abs_correction"] = n ? sum_abs / n : 0.0;
    report["max_abs_correction"] = max_abs;
    report["time_s"] = watch.seconds();
    return out;
}

void add_chart_correction(cv::Mat& target, const std::vector<std::array<int, 3>>& faces,
                          const std::unordered_map<int, Eigen::Vector2d>& texel_of,
                          const std::unordered_map<int, Eigen::Vector3f>& correction, int reach) {
    const int w = target.cols, h = target.rows;
    cv::Mat corr(h, w, CV_32FC3, cv::Scalar::all(0));
    cv::Mat covered(h, w, CV_8U, cv::Scalar(0));
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& [v, g] : correction) mean += g.cast<double>();
    if (!correction.empty()) mean /= static_cast<double>(correction.size());
    // Texel centres inside each face: barycentric interpolation of its corners' corrections.
    for (const auto& t : faces) {
        const Eigen::Vector2d& p0 = texel_of.at(t[0]);
        const Eigen::Vector2d& p1 = texel_of.at(t[1]);
        const Eigen::Vector2d& p2 = texel_of.at(t[2]);
        const Eigen::Vector3f g[3] = {correction.at(t[0]), correction.at(t[1]),
                                      correction.at(t[2])};
        const double det =
            (p1.x() - p0.x()) * (p2.y() - p0.y()) - (p2.x() - p0.x()) * (p1.y() - p0.y());
        if (!(std::abs(det) > 1e-12)) continue;
        const int x0 =
            std::max(0, static_cast<int>(std::floor(std::min({p0.x(), p1.x(), p2.x()}))));
        const int y0 =
            std::max(0, static_cast<int>(std::floor(std::min({p0.y(), p1.y(), p2.y()}))));
        const int x1 =
            std::min(w - 1, static_cast<int>(std::ceil(std::max({p0.x(), p1.x(), p2.x()}))));
        const int y1 =
            std::min(h - 1, static_cast<int>(std::ceil(std::max({p0.y(), p1.y(), p2.y()}))));
        for (int y = y0; y <= y1; ++y)
            for (int x = x0; x <= x1; ++x) {
                const double px = x + 0.5, py = y + 0.5;
                const double b1 =
                    ((px - p0.x()) * (p2.y() - p0.y()) - (p2.x() - p0.x()) * (py - p0.y())) / det;
                const double b2 =
                    ((p1.x() - p0.x()) * (py - p0.y()) - (px - p0.x()) * (p1.y() - p0.y())) / det;
                const double b0 = 1 - b1 - b2;
                if (b0 < -1e-9 || b1 < -1e-9 || b2 < -1e-9) continue;
                const Eigen::Vector3f c = static_cast<float>(b0) * g[0] +
                                          static_cast<float>(b1) * g[1] +
                                          static_cast<float>(b2) * g[2];
                corr.at<cv::Vec3f>(y, x) = {c[0], c[1], c[2]};
                covered.at<uchar>(y, x) = 1;
            }
    }
    // Texels next to the faces (read by bilinear lookups and mip-mapping): the mean of their
    // covered 8-neighbours, ring by ring.
    rgbd::internal::dilate_covered<float>(corr, covered, reach);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const cv::Vec3f c = covered.at<uchar>(y, x) ? corr.at<cv::Vec3f>(y, x)
                                                        : cv::Vec3f(static_cast<float>(mean[0]),
                                                                    static_cast<float>(mean[1]),
                                                                    static_cast<float>(mean[2]));
            cv::Vec3b& p = target.at<cv::Vec3b>(y, x);
            for (int ch = 0; ch < 3; ++ch) p[ch] = cv::saturate_cast<uchar>(p[ch] + c[ch]);
        }
}

}  // namespace rgbd::texture
