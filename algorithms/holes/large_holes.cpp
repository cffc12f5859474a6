#include "algorithms/holes/large_holes.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <Eigen/SparseLU>
#include <algorithm>
#include <cmath>
#include <functional>
#include <opencv2/imgproc.hpp>
#include <opencv2/photo.hpp>

#include "algorithms/holes/exemplar_inpaint.hpp"
#include "algorithms/internal/kd_tree.hpp"
#include "toolkit/error.hpp"

namespace rgbd::holes {

void InpaintOptions::check() const {
    RGBD_CHECK(std::isfinite(pixel) && pixel >= 0.5 && pixel <= 10,
               "inpaint: pixel size must be in [0.5, 10] spacings");
    RGBD_CHECK(std::isfinite(telea_radius) && telea_radius >= 1 && telea_radius <= 50,
               "inpaint: Telea radius must be in [1, 50] pixels");
    RGBD_CHECK(patch >= 3 && patch <= 51 && patch % 2 == 1,
               "inpaint: the exemplar patch side must be odd, in [3, 51] pixels");
    RGBD_CHECK(std::isfinite(search_window) && search_window >= 1 && search_window <= 100,
               "inpaint: the exemplar search window must be in [1, 100] hole boxes");
    RGBD_CHECK(std::isfinite(wrap) && wrap >= 0 && wrap <= 0.5,
               "inpaint: wrap padding must be in [0, 0.5] of the width");
    RGBD_CHECK(min_component >= 1 && min_component <= 1000000,
               "inpaint: minimum component must be in [1, 1e6] pixels");
    RGBD_CHECK(std::isfinite(step) && step >= 0.25 && step <= 10,
               "inpaint: step must be in [0.25, 10] spacings");
    RGBD_CHECK(std::isfinite(clearance) && clearance >= 0 && clearance <= 5,
               "inpaint: clearance must be in [0, 5] spacings");
    RGBD_CHECK(std::isfinite(min_rim_radial) && min_rim_radial >= -1 && min_rim_radial <= 1,
               "inpaint: minimum rim n.radial must be in [-1, 1]");
    RGBD_CHECK(std::isfinite(top_fraction) && top_fraction > 0 && top_fraction <= 0.5,
               "inpaint: top fraction must be in (0, 0.5]");
    RGBD_CHECK(std::isfinite(top_component) && top_component >= 0 && top_component <= 1,
               "inpaint: top component share must be in [0, 1]");
    RGBD_CHECK(blend_band >= 0 && blend_band <= 100, "inpaint: blend band must be in [0, 100]");
    RGBD_CHECK(std::isfinite(visible_max_angle_deg) && visible_max_angle_deg > 0 &&
                   visible_max_angle_deg < 90,
               "inpaint: visibility angle must be in (0, 90) degrees");
    RGBD_CHECK(std::isfinite(ray_clearance) && ray_clearance > 0 && ray_clearance <= 20,
               "inpaint: ray clearance must be in (0, 20] spacings");
    RGBD_CHECK(std::isfinite(max_ellipsoid_rms) && max_ellipsoid_rms > 0,
               "inpaint: the ellipsoid's residual limit must be positive");
}

namespace {

void check_input(const SurfacePoints& points, const std::vector<Eigen::Vector3d>& normals,
                 double spacing_m) {
    RGBD_CHECK(!points.position.empty(), "inpaint: no points");
    RGBD_CHECK(normals.size() == points.size(), "inpaint: one normal per point is needed");
    RGBD_CHECK(points.color.empty() || points.color.size() == points.size(),
               "inpaint: one colour per point is needed");
    RGBD_CHECK(std::isfinite(spacing_m) && spacing_m > 0, "inpaint: the spacing must be positive");
    for (const auto& p : points.position)
        RGBD_CHECK(p.allFinite(), "inpaint: non-finite point coordinates");
}

/// Right-handed frame (e1, e2, up).
void horizontal_frame(const Eigen::Vector3d& up, Eigen::Vector3d& e1, Eigen::Vector3d& e2) {
    const Eigen::Vector3d seed =
        std::abs(up.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
    e1 = (seed - seed.dot(up) * up).normalized();
    e2 = up.cross(e1);
}

/// Telea on every pixel of `unknown` (8-bit mask, non-zero = unknown), in place. Pixels outside
/// the object are unknown too, so that they never act as known zeros.
/// OpenCV's Telea adds a normalised gradient term and a rounding offset of 0.5 (meant for 8-bit
/// levels) to every pixel it fills, whatever the type: on a float image in metres that is an
/// error of metres. Float images (metres) are therefore inpainted in micrometres above their
/// known minimum, where the offset is a few micrometres.
void telea(cv::Mat& image, const cv::Mat& unknown, double radius) {
    if (cv::countNonZero(unknown) == 0) return;
    cv::Mat out;
    if (image.type() == CV_32F) {
        double lo = 0, hi = 0;
        cv::minMaxLoc(image, &lo, &hi, nullptr, nullptr, 255 - unknown);
        cv::Mat scaled;
        image.convertTo(scaled, CV_32F, 1e6, -lo * 1e6);
        scaled.setTo(0.0f, unknown);
        cv::inpaint(scaled, unknown, out, radius, cv::INPAINT_TELEA);
        out.convertTo(image, CV_32F, 1e-6, lo);
        return;
    }
    cv::inpaint(image, unknown, out, radius, cv::INPAINT_TELEA);
    image = out;
}

constexpr std::size_t kBiharmonicMaxPixels = 250000;

/// Biharmonic fill [M] of the float image on the non-zero pixels of `mask`: solves
/// Laplacian^2 u = 0 there (13-point stencil; the other pixels are fixed boundary values, image
/// borders clamped) with a sparse LU. Unlike OpenCV's Telea, which averages its neighbours and
/// so flattens a dome, it continues the rim's slope and curvature into the hole. Returns false
/// (image unchanged) when the solve fails or the hole has more than kBiharmonicMaxPixels.
bool biharmonic(cv::Mat& img, const cv::Mat& mask) {
    std::vector<cv::Point> pixels;
    cv::findNonZero(mask, pixels);
    if (pixels.empty()) return true;
    // The sparse LU's fill-in grows fast with the unknowns: a scene with holes of this size is
    // no bust; Telea's result stays.
    if (pixels.size() > kBiharmonicMaxPixels) return false;
    const int rows = img.rows, cols = img.cols;
    cv::Mat index(rows, cols, CV_32S, cv::Scalar(-1));
    for (std::size_t i = 0; i < pixels.size(); ++i) index.at<int>(pixels[i]) = static_cast<int>(i);
    std::vector<Eigen::Triplet<double>> triplets;
    triplets.reserve(pixels.size() * 13);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(pixels.size()));
    static const int kStencil[13][3] = {
        {0, 0, 20}, {-1, 0, -8}, {1, 0, -8}, {0, -1, -8}, {0, 1, -8}, {-1, -1, 2}, {-1, 1, 2},
        {1, -1, 2}, {1, 1, 2},   {-2, 0, 1}, {2, 0, 1},   {0, -2, 1}, {0, 2, 1}};
    for (std::size_t i = 0; i < pixels.size(); ++i) {
        for (const auto& st : kStencil) {
            const int r = std::clamp(pixels[i].y + st[0], 0, rows - 1);
            const int c = std::clamp(pixels[i].x + st[1], 0, cols - 1);
            const int j = index.at<int>(r, c);
            if (j >= 0)
                triplets.emplace_back(static_cast<int>(i), j, st[2]);
            else
                rhs[static_cast<Eigen::Index>(i)] -= st[2] * double(img.at<float>(r, c));
        }
    }
    Eigen::SparseMatrix<double> a(static_cast<Eigen::Index>(pixels.size()),
                                  static_cast<Eigen::Index>(pixels.size()));
    a.setFromTriplets(triplets.begin(), triplets.end());
    Eigen::SparseLU<Eigen::SparseMatrix<double>> lu;
    lu.compute(a);
    if (lu.info() != Eigen::Success) return false;
    const Eigen::VectorXd u = lu.solve(rhs);
    if (lu.info() != Eigen::Success || !u.allFinite()) return false;
    for (std::size_t i = 0; i < pixels.size(); ++i)
        img.at<float>(pixels[i]) = static_cast<float>(u[static_cast<Eigen::Index>(i)]);
    return true;
}

/// §12.2 colour of the `target` pixels: Criminisi's exemplars from the `source` pixels over the
/// Telea result already in `color` (kept where no exemplar fits). Report: method, patches,
/// pixels filled by exemplars, pixels left to Telea, time_s.
nlohmann::json inpaint_colour(cv::Mat& color, const cv::Mat& target, const cv::Mat& source,
                              const InpaintOptions& options) {
    nlohmann::json info;
    if (options.colour == ColourInpaint::kTelea) {
        info["method"] = "telea";
        return info;
    }
    Stopwatch watch;
    ExemplarOptions eo;
    eo.patch = options.patch;
    eo.search_window = options.search_window;
    const ExemplarStats s = exemplar_inpaint(color, target, source, eo);
    info["method"] = "criminisi";
    info["patches"] = s.patches;
    info["exemplar_pixels"] = s.filled;
    info["telea_pixels"] = s.unfilled;
    info["windows_widened"] = s.window_widened;
    info["patch"] = s.patch;
    info["time_s"] = watch.seconds();
    return info;
}

Rgb pixel_rgb(const cv::Mat& color, int row, int col) {
    const cv::Vec3b c = color.at<cv::Vec3b>(row, col);
    return {c[0], c[1], c[2]};
}

/// New points proposed by a fill, in parallel arrays: position, normal, colour and the hole
/// component (`loop`) of each.
struct Candidates {
    std::vector<Eigen::Vector3d> position, normal;
    std::vector<Rgb> color;
    std::vector<std::uint32_t> loop;

    void push(const Eigen::Vector3d& p, const Eigen::Vector3d& n, Rgb c, std::uint32_t l) {
        position.push_back(p);
        normal.push_back(n);
        color.push_back(c);
        loop.push_back(l);
    }
};

/// Appends candidates that keep `clearance` from the existing points, in the order given.
void add_clear(FillResult& result, const internal::KdTree& tree, double clearance,
               const Candidates& candidates, FillMechanism mechanism) {
    const auto& position = candidates.position;
    const auto& normal = candidates.normal;
    const auto& color = candidates.color;
    const auto& loop = candidates.loop;
    std::vector<std::uint8_t> keep(position.size(), 0);
    const double c2 = clearance * clearance;
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, position.size(), 256), [&](const auto& range) {
            for (std::size_t i = range.begin(); i != range.end(); ++i) {
                if (!position[i].allFinite() || !normal[i].allFinite()) continue;
                std::uint32_t nearest;
                double d2;
                keep[i] = !(c2 > 0 && tree.nearest_within(position[i], c2, nearest, d2));
            }
        });
    for (std::size_t i = 0; i < position.size(); ++i) {
        if (!keep[i]) continue;
        result.position.push_back(position[i]);
        result.normal.push_back(normal[i]);
        result.color.push_back(color[i]);
        result.mechanism.push_back(mechanism);
        result.loop.push_back(loop[i]);
    }
}

/// Drops the candidates of hole components that a sensor saw through (§10's visibility test on
/// the component's centre, mean normal and radius). Returns the number of components dropped.
int drop_openings(Candidates& candidates, const std::vector<SensorView>& sensors,
                  const internal::KdTree& tree, double spacing_m, const InpaintOptions& options) {
    auto& position = candidates.position;
    auto& normal = candidates.normal;
    auto& color = candidates.color;
    auto& loop = candidates.loop;
    if (sensors.empty() || options.fill_openings || position.empty()) return 0;
    const std::uint32_t n = *std::max_element(loop.begin(), loop.end()) + 1;
    std::vector<Eigen::Vector3d> centre(n, Eigen::Vector3d::Zero()),
        mean_n(n, Eigen::Vector3d::Zero());
    std::vector<std::size_t> count(n, 0);
    for (std::size_t i = 0; i < position.size(); ++i) {
        centre[loop[i]] += position[i];
        mean_n[loop[i]] += normal[i];
        ++count[loop[i]];
    }
    std::vector<double> radius(n, 0.0);
    for (std::uint32_t l = 0; l < n; ++l)
        if (count[l]) centre[l] /= double(count[l]);
    for (std::size_t i = 0; i < position.size(); ++i)
        radius[loop[i]] = std::max(radius[loop[i]], (position[i] - centre[loop[i]]).norm());
    std::vector<std::uint8_t> open(n, 0);
    int dropped = 0;
    tbb::parallel_for(std::uint32_t(0), n, [&](std::uint32_t l) {
        if (!count[l] || mean_n[l].norm() == 0) return;
        for (const auto& s : sensors)
            if (sensor_sees_region(s, centre[l], mean_n[l].normalized(), radius[l], spacing_m, tree,
                                   options.visible_max_angle_deg, options.ray_clearance)) {
                open[l] = 1;
                return;
            }
    });
    for (auto o : open) dropped += o;
    std::size_t k = 0;
    for (std::size_t i = 0; i < position.size(); ++i) {
        if (open[loop[i]]) continue;
        position[k] = position[i];
        normal[k] = normal[i];
        color[k] = color[i];
        loop[k++] = loop[i];
    }
    position.resize(k);
    normal.resize(k);
    color.resize(k);
    loop.resize(k);
    return dropped;
}

/// The common end of both fills: the candidates of components a sensor saw through are
/// dropped, the rest join `result` where they keep the clearance from `points`; the number of
/// dropped components goes to info["skipped_seen_through"].
void keep_candidates(Candidates& candidates, const SurfacePoints& points,
                     const std::vector<SensorView>& sensors, double spacing_m,
                     const InpaintOptions& options, FillMechanism mechanism, FillResult& result,
                     Report& info) {
    const internal::KdTree tree(points.position);
    info["skipped_seen_through"] = drop_openings(candidates, sensors, tree, spacing_m, options);
    add_clear(result, tree, options.clearance * spacing_m, candidates, mechanism);
}

double bilinear(const cv::Mat& img, double row, double col, bool wrap_cols) {
    const int rows = img.rows, cols = img.cols;
    row = std::clamp(row, 0.0, double(rows - 1));
    if (!wrap_cols) col = std::clamp(col, 0.0, double(cols - 1));
    const int r0 = std::min(static_cast<int>(std::floor(row)), rows - 1);
    const int r1 = std::min(r0 + 1, rows - 1);
    const int c0f = static_cast<int>(std::floor(col));
    const double fr = row - r0, fc = col - c0f;
    auto at = [&](int r, int c) {
        c = wrap_cols ? ((c % cols) + cols) % cols : std::clamp(c, 0, cols - 1);
        return double(img.at<float>(r, c));
    };
    return (1 - fr) * ((1 - fc) * at(r0, c0f) + fc * at(r0, c0f + 1)) +
           fr * ((1 - fc) * at(r1, c0f) + fc * at(r1, c0f + 1));
}

}  // namespace

BodyAxis estimate_body_axis(const SurfacePoints& points, const std::vector<SensorView>& sensors) {
    RGBD_CHECK(!points.position.empty(), "body axis: no points");
    BodyAxis axis;
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const auto& p : points.position) centroid += p;
    centroid /= double(points.size());
    axis.origin = centroid;
    if (sensors.size() >= 3) {
        Eigen::Vector3d mean = Eigen::Vector3d::Zero();
        for (const auto& s : sensors) mean += s.world_from_sensor.translation();
        mean /= double(sensors.size());
        Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
        Eigen::Vector3d camera_up = Eigen::Vector3d::Zero();
        for (const auto& s : sensors) {
            const Eigen::Vector3d d = s.world_from_sensor.translation() - mean;
            cov += d * d.transpose();
            camera_up -= s.world_from_sensor.linear().col(1);  // image y points down
        }
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
        const Eigen::Vector3d l = eig.eigenvalues();
        // A plane: the two larger spreads comparable, the smallest one much smaller.
        if (l[1] > 1e-6 && l[0] < 0.05 * l[1] && camera_up.norm() > 1e-9) {
            axis.up = eig.eigenvectors().col(0).normalized();
            if (axis.up.dot(camera_up) < 0) axis.up = -axis.up;
            axis.from_sensors = true;
            return axis;
        }
    }
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const auto& p : points.position) {
        const Eigen::Vector3d d = p - centroid;
        cov += d * d.transpose();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    Eigen::Vector3d up = eig.eigenvectors().col(2).normalized();
    // The narrower end is the top: mean distance from the axis in the top and bottom tenths.
    std::vector<double> h;
    h.reserve(points.size());
    for (const auto& p : points.position) h.push_back((p - centroid).dot(up));
    std::vector<double> sorted = h;
    std::sort(sorted.begin(), sorted.end());
    const double lo = sorted[sorted.size() / 10], hi = sorted[sorted.size() * 9 / 10];
    double width_lo = 0, width_hi = 0;
    std::size_t n_lo = 0, n_hi = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
        const Eigen::Vector3d d = points.position[i] - centroid;
        const double w = (d - h[i] * up).norm();
        if (h[i] <= lo) width_lo += w, ++n_lo;
        if (h[i] >= hi) width_hi += w, ++n_hi;
    }
    if (n_lo && n_hi && width_hi / n_hi > width_lo / n_lo) up = -up;
    axis.up = up;
    return axis;
}

double head_top_start(const SurfacePoints& points, const BodyAxis& axis,
                      const InpaintOptions& options) {
    double h_min = std::numeric_limits<double>::infinity(), h_max = -h_min;
    for (const auto& p : points.position) {
        const double h = (p - axis.origin).dot(axis.up);
        h_min = std::min(h_min, h);
        h_max = std::max(h_max, h);
    }
    return h_max - options.top_fraction * (h_max - h_min);
}

FillResult fill_head_top(const SurfacePoints& points, const std::vector<Eigen::Vector3d>& normals,
                         const BodyAxis& axis, double spacing_m,
                         const std::vector<SensorView>& sensors, const InpaintOptions& options,
                         Report* report, const Progress& progress) {
    options.check();
    check_input(points, normals, spacing_m);
    Stopwatch watch;
    FillResult result;
    Eigen::Vector3d e1, e2;
    horizontal_frame(axis.up, e1, e2);
    const Eigen::Vector3d& up = axis.up;
    const double start = head_top_start(points, axis, options);
    // Step 1-2: the top region in (u, v, h) and its top-down height map.
    std::vector<Eigen::Vector3d> top;  // (u, v, h)
    std::vector<Rgb> top_color;
    for (std::size_t i = 0; i < points.size(); ++i) {
        const Eigen::Vector3d d = points.position[i] - axis.origin;
        const double h = d.dot(up);
        if (h < start) continue;
        top.emplace_back(d.dot(e1), d.dot(e2), h);
        top_color.push_back(points.color.empty() ? Rgb{128, 128, 128} : points.color[i]);
    }
    Report info;
    info["top_points"] = top.size();
    auto finish = [&]() {
        info["points_added"] = result.position.size();
        info["time_s"] = watch.seconds();
        if (report) (*report)["head_top"] = info;
        return result;
    };
    if (top.size() < 10) return finish();
    const double px = options.pixel * spacing_m;
    double u0 = std::numeric_limits<double>::infinity(), v0 = u0, u1 = -u0, v1 = -u0;
    for (const auto& t : top) {
        u0 = std::min(u0, t.x()), u1 = std::max(u1, t.x());
        v0 = std::min(v0, t.y()), v1 = std::max(v1, t.y());
    }
    const int margin = 2;
    const int cols = static_cast<int>(std::ceil((u1 - u0) / px)) + 1 + 2 * margin;
    const int rows = static_cast<int>(std::ceil((v1 - v0) / px)) + 1 + 2 * margin;
    RGBD_CHECK_AS(AlgorithmError, double(cols) * rows < 64e6,
                  "head top: the height map would have " + std::to_string(cols) + " x " +
                      std::to_string(rows) + " pixels (spacing too small for the object?)");
    info["image"] = {cols, rows};
    const double ou = u0 - margin * px, ov = v0 - margin * px;
    cv::Mat height(rows, cols, CV_32F, cv::Scalar(-std::numeric_limits<float>::infinity()));
    cv::Mat color(rows, cols, CV_8UC3, cv::Scalar(0, 0, 0));
    cv::Mat known(rows, cols, CV_8U, cv::Scalar(0));
    for (std::size_t i = 0; i < top.size(); ++i) {
        const int c = static_cast<int>((top[i].x() - ou) / px);
        const int r = static_cast<int>((top[i].y() - ov) / px);
        if (top[i].z() > height.at<float>(r, c)) {
            height.at<float>(r, c) = static_cast<float>(top[i].z());
            color.at<cv::Vec3b>(r, c) = {top_color[i].r, top_color[i].g, top_color[i].b};
            known.at<std::uint8_t>(r, c) = 255;
        }
    }
    // Step 3: hole = unknown pixels inside the convex hull of the known ones.
    std::vector<cv::Point> known_px, hull;
    cv::findNonZero(known, known_px);
    cv::convexHull(known_px, hull);
    cv::Mat inside(rows, cols, CV_8U, cv::Scalar(0));
    cv::fillConvexPoly(inside, hull, cv::Scalar(255));
    cv::Mat unknown = 255 - known;
    cv::Mat hole;
    cv::bitwise_and(inside, unknown, hole);
    // The hull's own outline pixels can be empty between two rim samples: only interior.
    cv::Mat eroded;
    cv::erode(inside, eroded, cv::Mat::ones(3, 3, CV_8U));
    cv::bitwise_and(hole, eroded, hole);
    // Scattered empty pixels among known ones (sampling gaps on steep or rough tops) are not
    // the crown: components smaller than min_component or than top_component x the largest
    // one are left to §11.
    cv::Mat labels;
    {
        cv::Mat stats, centroids;
        const int n = cv::connectedComponentsWithStats(hole, labels, stats, centroids, 8, CV_32S);
        int largest = 0;
        for (int l = 1; l < n; ++l) largest = std::max(largest, stats.at<int>(l, cv::CC_STAT_AREA));
        const double keep =
            std::max<double>(options.min_component, options.top_component * largest);
        int dropped = 0;
        for (int r = 0; r < rows; ++r)
            for (int c = 0; c < cols; ++c) {
                const int l = labels.at<int>(r, c);
                if (l > 0 && stats.at<int>(l, cv::CC_STAT_AREA) < keep) {
                    hole.at<std::uint8_t>(r, c) = 0;
                    ++dropped;
                }
            }
        info["components"] = n - 1;
        info["skipped_small_pixels"] = dropped;
    }
    const int hole_pixels = cv::countNonZero(hole);
    info["hole_pixels"] = hole_pixels;
    if (hole_pixels == 0) return finish();
    // Step 4: Telea on height and colour (every unknown pixel, so none is a known zero).
    height.setTo(0.0f, unknown);
    telea(height, unknown, options.telea_radius);
    telea(color, unknown, options.telea_radius);
    info["colour"] = inpaint_colour(color, hole, known, options);
    if (options.biharmonic) info["biharmonic"] = biharmonic(height, hole);
    if (!report_progress(progress, 0.4)) throw AlgorithmError("cancelled");
    if (options.ellipsoid) {
        // Axis-aligned ellipsoid A u^2 + B v^2 + C h^2 + D u + E v + F h = 1 (least squares,
        // coordinates centred and scaled for conditioning).
        Eigen::Vector3d mean = Eigen::Vector3d::Zero();
        for (const auto& t : top) mean += t;
        mean /= double(top.size());
        double scale = 0;
        for (const auto& t : top) scale = std::max(scale, (t - mean).cwiseAbs().maxCoeff());
        Eigen::Matrix<double, 6, 6> ata = Eigen::Matrix<double, 6, 6>::Zero();
        Eigen::Matrix<double, 6, 1> atb = Eigen::Matrix<double, 6, 1>::Zero();
        for (const auto& t : top) {
            const Eigen::Vector3d q = (t - mean) / scale;
            Eigen::Matrix<double, 6, 1> row;
            row << q.x() * q.x(), q.y() * q.y(), q.z() * q.z(), q.x(), q.y(), q.z();
            ata += row * row.transpose();
            atb += row;
        }
        const Eigen::Matrix<double, 6, 1> k = ata.ldlt().solve(atb);
        bool valid = k.allFinite() && k[0] > 0 && k[1] > 0 && k[2] > 0;
        // Fit residual, geometric to first order (|f| / |grad f|), in spacings: a top that is
        // not an ellipsoid (a wreath, a hat) is left open (or keeps the inpainted heights with
        // top_without_ellipsoid).
        double sq = 0;
        for (const auto& t : top) {
            const Eigen::Vector3d q = (t - mean) / scale;
            const double f = k[0] * q.x() * q.x() + k[1] * q.y() * q.y() + k[2] * q.z() * q.z() +
                             k[3] * q.x() + k[4] * q.y() + k[5] * q.z() - 1;
            const Eigen::Vector3d g(2 * k[0] * q.x() + k[3], 2 * k[1] * q.y() + k[4],
                                    2 * k[2] * q.z() + k[5]);
            const double d = scale * std::abs(f) / std::max(g.norm(), 1e-12);
            sq += d * d;
        }
        const double rms = std::sqrt(sq / double(top.size())) / spacing_m;
        info["ellipsoid_rms_spacings"] = rms;
        valid = valid && rms <= options.max_ellipsoid_rms;
        info["ellipsoid"] = valid;
        if (!valid && !options.top_without_ellipsoid) {
            // Not an ellipsoid (a wreath, a hat): nothing trustworthy to continue; the crown
            // stays open rather than invented.
            info["hole_pixels_left_open"] = hole_pixels;
            return finish();
        }
        if (valid) {
            // Centre and semi-axes (normalised units), for the report.
            const Eigen::Vector3d c(-k[3] / (2 * k[0]), -k[4] / (2 * k[1]), -k[5] / (2 * k[2]));
            const double g = 1 + k[0] * c.x() * c.x() + k[1] * c.y() * c.y() + k[2] * c.z() * c.z();
            if (g > 0)
                info["ellipsoid_semi_axes_m"] = {scale * std::sqrt(g / k[0]),
                                                 scale * std::sqrt(g / k[1]),
                                                 scale * std::sqrt(g / k[2])};
            cv::Mat distance;
            cv::distanceTransform(hole, distance, cv::DIST_L2, 3);
            int used = 0;
            for (int r = 0; r < rows; ++r)
                for (int c2 = 0; c2 < cols; ++c2) {
                    if (!hole.at<std::uint8_t>(r, c2)) continue;
                    const double u = (ou + (c2 + 0.5) * px - mean.x()) / scale;
                    const double v = (ov + (r + 0.5) * px - mean.y()) / scale;
                    // C h^2 + F h + (A u^2 + B v^2 + D u + E v - 1) = 0, upper root.
                    const double cc = k[0] * u * u + k[1] * v * v + k[3] * u + k[4] * v - 1;
                    const double disc = k[5] * k[5] - 4 * k[2] * cc;
                    if (disc < 0) continue;
                    const double h = (-k[5] + std::sqrt(disc)) / (2 * k[2]) * scale + mean.z();
                    const double w =
                        options.blend_band > 0
                            ? std::min(1.0, double(distance.at<float>(r, c2)) / options.blend_band)
                            : 1.0;
                    float& cell = height.at<float>(r, c2);
                    cell = static_cast<float>(w * h + (1 - w) * cell);
                    ++used;
                }
            info["ellipsoid_pixels"] = used;
        }
    }
    if (!report_progress(progress, 0.7)) throw AlgorithmError("cancelled");
    // Step 5: back-projection of the hole pixels at the step, normals from the gradient.
    const int n_sub = std::max(1, static_cast<int>(std::lround(options.pixel / options.step)));
    Candidates cand;
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            if (!hole.at<std::uint8_t>(r, c)) continue;
            const int cl = std::max(c - 1, 0), cr = std::min(c + 1, cols - 1);
            const int rl = std::max(r - 1, 0), rr = std::min(r + 1, rows - 1);
            const double hu =
                (height.at<float>(r, cr) - height.at<float>(r, cl)) / (std::max(cr - cl, 1) * px);
            const double hv =
                (height.at<float>(rr, c) - height.at<float>(rl, c)) / (std::max(rr - rl, 1) * px);
            const Eigen::Vector3d n = (up - hu * e1 - hv * e2).normalized();
            for (int a = 0; a < n_sub; ++a)
                for (int b = 0; b < n_sub; ++b) {
                    const double fc = c + (a + 0.5) / n_sub - 0.5;  // pixel-centre coordinates
                    const double fr = r + (b + 0.5) / n_sub - 0.5;
                    const double h = bilinear(height, fr, fc, false);
                    const double u = ou + (fc + 0.5) * px, v = ov + (fr + 0.5) * px;
                    cand.push(axis.origin + u * e1 + v * e2 + h * up, n, pixel_rgb(color, r, c),
                              static_cast<std::uint32_t>(labels.at<int>(r, c)));
                }
        }
    keep_candidates(cand, points, sensors, spacing_m, options, FillMechanism::kHeadTop, result,
                    info);
    if (!report_progress(progress, 1.0)) throw AlgorithmError("cancelled");
    return finish();
}

FillResult fill_large_holes(const SurfacePoints& points,
                            const std::vector<Eigen::Vector3d>& normals, const BodyAxis& axis,
                            double spacing_m, const std::vector<SensorView>& sensors,
                            const InpaintOptions& options, double top_limit, Report* report,
                            const Progress& progress) {
    options.check();
    check_input(points, normals, spacing_m);
    Stopwatch watch;
    FillResult result;
    Report info;
    Eigen::Vector3d e1, e2;
    horizontal_frame(axis.up, e1, e2);
    const Eigen::Vector3d& up = axis.up;
    // §12.1 step 2: cylindrical coordinates (theta from e1 towards e2).
    const std::size_t n = points.size();
    std::vector<double> theta(n), hh(n), rad(n);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1024), [&](const auto& range) {
        for (std::size_t i = range.begin(); i != range.end(); ++i) {
            const Eigen::Vector3d d = points.position[i] - axis.origin;
            const double x = d.dot(e1), y = d.dot(e2);
            theta[i] = std::atan2(y, x);
            hh[i] = d.dot(up);
            rad[i] = std::hypot(x, y);
        }
    });
    auto finish = [&]() {
        info["points_added"] = result.position.size();
        info["time_s"] = watch.seconds();
        if (report) (*report)["large_holes"] = info;
        return result;
    };
    if (n < 10) return finish();
    // Step 3: image grid; a column spans an angle sized for the 10th-percentile radius.
    const double px = options.pixel * spacing_m;
    std::vector<double> sorted = rad;
    std::nth_element(sorted.begin(), sorted.begin() + n / 10, sorted.end());
    const double r10 = std::max(sorted[n / 10], px);
    const double h_min = *std::min_element(hh.begin(), hh.end());
    const double h_max = *std::max_element(hh.begin(), hh.end());
    const int rows = static_cast<int>(std::ceil((h_max - h_min) / px)) + 1;
    const int cols = std::max(8, static_cast<int>(std::ceil(2 * M_PI * r10 / px)));
    RGBD_CHECK_AS(AlgorithmError, double(cols) * rows < 64e6,
                  "large holes: the cylinder image would have " + std::to_string(cols) + " x " +
                      std::to_string(rows) + " pixels (spacing too small for the object?)");
    info["image"] = {cols, rows};
    const double dtheta = 2 * M_PI / cols;
    // Step 4: splat, the largest radius per pixel wins (outer surface), with its colour and
    // its normal's radial component.
    cv::Mat radius(rows, cols, CV_32F, cv::Scalar(-1.0f));
    cv::Mat color(rows, cols, CV_8UC3, cv::Scalar(0, 0, 0));
    cv::Mat radial(rows, cols, CV_32F, cv::Scalar(0.0f));
    for (std::size_t i = 0; i < n; ++i) {
        const int r = std::clamp(static_cast<int>((hh[i] - h_min) / px), 0, rows - 1);
        const int c = std::clamp(static_cast<int>((theta[i] + M_PI) / dtheta), 0, cols - 1);
        if (rad[i] <= radius.at<float>(r, c)) continue;
        radius.at<float>(r, c) = static_cast<float>(rad[i]);
        const Rgb col = points.color.empty() ? Rgb{128, 128, 128} : points.color[i];
        color.at<cv::Vec3b>(r, c) = {col.r, col.g, col.b};
        const Eigen::Vector3d d = points.position[i] - axis.origin;
        const Eigen::Vector3d out = (d - d.dot(up) * up).normalized();
        radial.at<float>(r, c) = static_cast<float>(normals[i].dot(out));
    }
    cv::Mat known = radius >= 0.0f;
    // Step 5 [M]: hole = unknown pixels between the lowest and the highest known pixel of their
    // column (the bottom cut and the top stay outside), below the head top's region.
    cv::Mat hole(rows, cols, CV_8U, cv::Scalar(0));
    const int top_row =
        std::isfinite(top_limit)
            ? std::clamp(static_cast<int>(std::floor((top_limit - h_min) / px)), -1, rows - 1)
            : rows - 1;
    for (int c = 0; c < cols; ++c) {
        int lo = -1, hi = -1;
        for (int r = 0; r < rows; ++r)
            if (known.at<std::uint8_t>(r, c)) {
                if (lo < 0) lo = r;
                hi = r;
            }
        for (int r = lo + 1; r < std::min(hi, top_row + 1); ++r)
            if (!known.at<std::uint8_t>(r, c)) hole.at<std::uint8_t>(r, c) = 255;
    }
    // Components (with the circular wrap), small ones left to §11, the star-shape test on the
    // rim normals.
    const int pad = std::max(1, static_cast<int>(std::ceil(options.wrap * cols)));
    auto wrap_pad = [&](const cv::Mat& img) {
        cv::Mat out;
        cv::copyMakeBorder(img, out, 0, 0, std::min(pad, cols), std::min(pad, cols),
                           cv::BORDER_WRAP);
        return out;
    };
    cv::Mat labels;
    const int n_labels = cv::connectedComponents(hole, labels, 8, CV_32S);
    // Merge labels across the seam (column 0 and column cols - 1 touch).
    std::vector<int> parent(n_labels);
    for (int l = 0; l < n_labels; ++l) parent[l] = l;
    std::function<int(int)> find = [&](int l) {
        return parent[l] == l ? l : parent[l] = find(parent[l]);
    };
    for (int r = 0; r < rows; ++r)
        for (int dr = -1; dr <= 1; ++dr) {
            const int r2 = r + dr;
            if (r2 < 0 || r2 >= rows) continue;
            const int a = labels.at<int>(r, 0), b = labels.at<int>(r2, cols - 1);
            if (a > 0 && b > 0) parent[find(a)] = find(b);
        }
    std::vector<int> size(n_labels, 0);
    std::vector<double> rim_sum(n_labels, 0.0);
    std::vector<int> rim_count(n_labels, 0);
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            const int l = labels.at<int>(r, c);
            if (l > 0) {
                ++size[find(l)];
                continue;
            }
            if (!known.at<std::uint8_t>(r, c)) continue;
            // A known pixel next to a hole pixel is on that hole's rim.
            int seen = -1;
            for (int dr = -1; dr <= 1; ++dr)
                for (int dc = -1; dc <= 1; ++dc) {
                    const int r2 = r + dr;
                    if (r2 < 0 || r2 >= rows) continue;
                    const int l2 = labels.at<int>(r2, ((c + dc) % cols + cols) % cols);
                    if (l2 <= 0) continue;
                    const int root = find(l2);
                    if (root == seen) continue;
                    seen = root;
                    rim_sum[root] += radial.at<float>(r, c);
                    ++rim_count[root];
                }
        }
    std::vector<std::uint8_t> fill(n_labels, 0);
    int filled = 0, too_small = 0, not_star = 0;
    for (int l = 1; l < n_labels; ++l) {
        if (find(l) != l || size[l] == 0) continue;
        if (size[l] < options.min_component) {
            ++too_small;
            continue;
        }
        if (rim_count[l] == 0 || rim_sum[l] / rim_count[l] < options.min_rim_radial) {
            ++not_star;
            continue;
        }
        fill[l] = 1;
        ++filled;
    }
    cv::Mat target(rows, cols, CV_8U, cv::Scalar(0));
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            const int l = labels.at<int>(r, c);
            if (l > 0 && fill[find(l)]) target.at<std::uint8_t>(r, c) = 255;
        }
    info["hole_components"] = filled;
    info["skipped_small"] = too_small;
    info["skipped_not_star_shaped"] = not_star;
    const int target_pixels = cv::countNonZero(target);
    info["hole_pixels"] = target_pixels;
    if (target_pixels == 0) return finish();
    if (!report_progress(progress, 0.2)) throw AlgorithmError("cancelled");
    // §12.2: Telea on radius and colour, on the wrap-padded images (every unknown pixel is
    // inpainted so that none acts as a known zero; only the target ones are used).
    cv::Mat unknown = 255 - known;
    radius.setTo(0.0f, unknown);
    cv::Mat r_wide = wrap_pad(radius), c_wide = wrap_pad(color), u_wide = wrap_pad(unknown);
    telea(r_wide, u_wide, options.telea_radius);
    telea(c_wide, u_wide, options.telea_radius);
    const cv::Rect crop(std::min(pad, cols), 0, cols, rows);
    {
        // Exemplars for the target pixels of the centre copy only (the padding's copies of them
        // are cropped away); source patches anywhere, across the seam too.
        cv::Mat t_centre = cv::Mat::zeros(r_wide.size(), CV_8U);
        target.copyTo(t_centre(crop));
        info["colour"] = inpaint_colour(c_wide, t_centre, wrap_pad(known), options);
    }
    if (options.biharmonic) {
        cv::Mat t_wide = wrap_pad(target);
        info["biharmonic"] = biharmonic(r_wide, t_wide);
    }
    // §12.3: 3x3 median inside the filled region only.
    if (options.median) {
        cv::Mat med;
        cv::medianBlur(r_wide, med, 3);
        med(crop).copyTo(r_wide(crop), target);
    }
    radius = r_wide(crop).clone();
    color = c_wide(crop).clone();
    if (!report_progress(progress, 0.6)) throw AlgorithmError("cancelled");
    // Back to 3D: hole pixels only, resampled at the step by bilinear interpolation.
    Candidates cand;
    const double step = options.step * spacing_m;
    const int n_h = std::max(1, static_cast<int>(std::lround(px / step)));
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            if (!target.at<std::uint8_t>(r, c)) continue;
            const float r0 = radius.at<float>(r, c);
            const int n_t = std::max(1, static_cast<int>(std::lround(r0 * dtheta / step)));
            const int cl = (c + cols - 1) % cols, cr = (c + 1) % cols;
            const int rl = std::max(r - 1, 0), rh = std::min(r + 1, rows - 1);
            const double r_t = (radius.at<float>(r, cr) - radius.at<float>(r, cl)) / (2 * dtheta);
            const double r_h =
                (radius.at<float>(rh, c) - radius.at<float>(rl, c)) / (std::max(rh - rl, 1) * px);
            for (int a = 0; a < n_t; ++a)
                for (int b = 0; b < n_h; ++b) {
                    const double fc = c + (a + 0.5) / n_t - 0.5;
                    const double fr = r + (b + 0.5) / n_h - 0.5;
                    const double rr = bilinear(radius, fr, fc, true);
                    const double th = -M_PI + (fc + 0.5) * dtheta;
                    const double h = h_min + (fr + 0.5) * px;
                    const Eigen::Vector3d out = std::cos(th) * e1 + std::sin(th) * e2;
                    const Eigen::Vector3d tangent = out.cross(up);  // d(out)/d(theta) = -tangent
                    // P(theta, h) = origin + r out + h up.
                    const Eigen::Vector3d dp_dt = r_t * out - rr * tangent;
                    const Eigen::Vector3d dp_dh = r_h * out + up;
                    Eigen::Vector3d nn = dp_dt.cross(dp_dh).normalized();
                    if (nn.dot(out) < 0) nn = -nn;
                    cand.push(axis.origin + rr * out + h * up, nn, pixel_rgb(color, r, c),
                              static_cast<std::uint32_t>(find(labels.at<int>(r, c))));
                }
        }
    keep_candidates(cand, points, sensors, spacing_m, options, FillMechanism::kLargeHole, result,
                    info);
    if (!report_progress(progress, 1.0)) throw AlgorithmError("cancelled");
    return finish();
}

}  // namespace rgbd::holes
