#include "algorithms/reconstruction/smooth_points.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <utility>

#include "algorithms/internal/kd_tree.hpp"
#include "toolkit/error.hpp"

namespace rgbd::reconstruction::internal {

std::size_t smooth_points(std::vector<Eigen::Vector3d>& points,
                          std::vector<Eigen::Vector3d>& normals, const SmoothOptions& o) {
    RGBD_CHECK(points.size() == normals.size(), "smooth_points: points and normals differ");
    RGBD_CHECK(o.radius > 0 && std::isfinite(o.radius), "smooth_points: radius must be > 0");
    const double cos_max = std::cos(o.max_normal_angle_deg * M_PI / 180.0);
    const double inv_two_sigma2 = 1.0 / (2.0 * 0.25 * o.radius * o.radius);  // sigma = r / 2
    std::size_t moved = 0;
    for (int round = 0; round < o.iterations; ++round) {
        const std::vector<Eigen::Vector3d> src = points, src_n = normals;
        const rgbd::internal::KdTree tree(src);
        std::vector<unsigned char> did(src.size(), 0);
        tbb::parallel_for(
            tbb::blocked_range<std::size_t>(0, src.size(), 512),
            [&](const tbb::blocked_range<std::size_t>& range) {
                std::vector<std::pair<std::uint32_t, double>> nb;
                std::vector<std::pair<std::uint32_t, double>> used;  // index, weight
                for (std::size_t i = range.begin(); i != range.end(); ++i) {
                    const Eigen::Vector3d& p = src[i];
                    const Eigen::Vector3d& n = src_n[i];
                    tree.radius(p, o.radius, nb, false);
                    used.clear();
                    double w_sum = 0;
                    Eigen::Vector3d c = Eigen::Vector3d::Zero();
                    for (const auto& [j, d2] : nb) {
                        if (src_n[j].dot(n) < cos_max) continue;
                        const double w = std::exp(-d2 * inv_two_sigma2);
                        used.emplace_back(j, w);
                        w_sum += w;
                        c += w * src[j];
                    }
                    if (static_cast<int>(used.size()) < o.min_neighbors || w_sum <= 0) continue;
                    c /= w_sum;
                    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
                    for (const auto& [j, w] : used) {
                        const Eigen::Vector3d d = src[j] - c;
                        cov.noalias() += w * d * d.transpose();
                    }
                    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
                    eig.computeDirect(cov);
                    Eigen::Vector3d m = eig.eigenvectors().col(0).normalized();
                    if (m.dot(n) < 0) m = -m;
                    const Eigen::Vector3d u = eig.eigenvectors().col(2).normalized();
                    const Eigen::Vector3d v = m.cross(u);
                    const Eigen::Vector3d pl = p - c;
                    const double xi = pl.dot(u), yi = pl.dot(v);
                    Eigen::Vector3d q = p - pl.dot(m) * m;  // plane projection
                    Eigen::Vector3d qn = m;
                    if (static_cast<int>(used.size()) >= o.quadric_neighbors) {
                        // Weighted least squares of z = a + b x + c y + d x^2 + e xy + f y^2.
                        Eigen::Matrix<double, 6, 6> ata = Eigen::Matrix<double, 6, 6>::Zero();
                        Eigen::Matrix<double, 6, 1> atb = Eigen::Matrix<double, 6, 1>::Zero();
                        const double s = 1.0 / o.radius;  // scale x, y for conditioning
                        for (const auto& [j, w] : used) {
                            const Eigen::Vector3d d = src[j] - c;
                            const double x = d.dot(u) * s, y = d.dot(v) * s, z = d.dot(m);
                            Eigen::Matrix<double, 6, 1> row;
                            row << 1, x, y, x * x, x * y, y * y;
                            ata.noalias() += w * row * row.transpose();
                            atb.noalias() += w * z * row;
                        }
                        const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(ata);
                        if (ldlt.info() == Eigen::Success && ldlt.isPositive()) {
                            const Eigen::Matrix<double, 6, 1> k = ldlt.solve(atb);
                            const double x = xi * s, y = yi * s;
                            const double z = k(0) + k(1) * x + k(2) * y + k(3) * x * x +
                                             k(4) * x * y + k(5) * y * y;
                            if (k.allFinite() && std::abs(z - pl.dot(m)) < 0.5 * o.radius) {
                                q = c + xi * u + yi * v + z * m;
                                const double hx = (k(1) + 2 * k(3) * x + k(4) * y) * s;
                                const double hy = (k(2) + k(4) * x + 2 * k(5) * y) * s;
                                qn = (m - hx * u - hy * v).normalized();
                            }
                        }
                    }
                    if (!q.allFinite() || !qn.allFinite()) continue;
                    points[i] = q;
                    normals[i] = qn;
                    did[i] = 1;
                }
            });
        if (round + 1 == o.iterations)
            for (unsigned char d : did) moved += d;
    }
    return moved;
}

}  // namespace rgbd::reconstruction::internal
