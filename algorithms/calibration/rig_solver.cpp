#include "algorithms/calibration/rig_solver.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <queue>

#include "toolkit/error.hpp"

namespace rgbd::calibration {
namespace {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix26 = Eigen::Matrix<double, 2, 6>;

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
    Eigen::Matrix3d m;
    m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
    return m;
}

/// Left update exp(delta) * pose, delta = (translation, rotation vector).
Pose left_update(const Vector6d& delta, const Pose& pose) {
    const Eigen::Vector3d phi = delta.tail<3>();
    const double angle = phi.norm();
    const Eigen::Matrix3d r = angle > 0 ? Eigen::AngleAxisd(angle, phi / angle).toRotationMatrix()
                                        : Eigen::Matrix3d::Identity();
    Pose out = Pose::Identity();
    out.linear() = r * pose.linear();
    out.translation() = r * pose.translation() + delta.head<3>();
    return orthonormalized(out);
}

/// Links between cameras: for each frame set, the cameras that saw the board.
std::map<int, std::vector<int>> by_frameset(const std::vector<Observation>& observations) {
    std::map<int, std::vector<int>> sets;
    for (std::size_t i = 0; i < observations.size(); ++i)
        sets[observations[i].frameset].push_back(static_cast<int>(i));
    return sets;
}

struct Problem {
    const std::vector<PinholeIntrinsics>& intrinsics;
    const std::vector<Observation>& observations;
    const BoardSpec& board;
    std::vector<int> used;          ///< observations in the solve
    std::vector<int> board_of;      ///< observation -> board unknown (-1 = not used)
    std::vector<int> camera_block;  ///< camera -> block index (-1 = fixed or unused)
    int camera_blocks = 0;
    int boards = 0;
};

/// Reprojection residual of one corner and its Jacobians (camera left update, board left update).
Eigen::Vector2d residual(const PinholeIntrinsics& k, const Pose& camera_from_anchor,
                         const Pose& anchor_from_board, const Eigen::Vector3d& corner,
                         const Eigen::Vector2d& pixel, Matrix26* j_camera, Matrix26* j_board) {
    const Eigen::Vector3d q = anchor_from_board * corner;
    const Eigen::Vector3d p = camera_from_anchor * q;
    const Eigen::Vector2d u = k.project(p);
    if (j_camera || j_board) {
        const double iz = 1.0 / p.z();
        Eigen::Matrix<double, 2, 3> du;
        du << k.fx * iz, 0, -k.fx * p.x() * iz * iz, 0, k.fy * iz, -k.fy * p.y() * iz * iz;
        if (j_camera) {
            j_camera->leftCols<3>() = du;
            j_camera->rightCols<3>() = -du * skew(p);
        }
        if (j_board) {
            const Eigen::Matrix<double, 2, 3> dq = du * camera_from_anchor.linear();
            j_board->leftCols<3>() = dq;
            j_board->rightCols<3>() = -dq * skew(q);
        }
    }
    return u - pixel;
}

double huber_weight(double r, double k) { return r <= k ? 1.0 : k / r; }

}  // namespace

void RigSolveOptions::check() const {
    RGBD_CHECK(anchor >= 0, "anchor must be >= 0");
    check_range("iterations", max_iterations, Range::closed(1, 10000));
    RGBD_CHECK(std::isfinite(huber_px) && huber_px > 0, "Huber scale must be > 0 px");
}

std::vector<int> unconnected_cameras(int cameras, const std::vector<Observation>& observations,
                                     int anchor) {
    std::vector<std::vector<int>> adjacent(cameras);
    for (const auto& [set, list] : by_frameset(observations))
        for (int a : list)
            for (int b : list) {
                const int sa = observations[a].sensor, sb = observations[b].sensor;
                if (sa != sb) adjacent[sa].push_back(sb);
            }
    std::vector<bool> seen(cameras, false);
    std::queue<int> queue;
    if (anchor >= 0 && anchor < cameras) {
        seen[anchor] = true;
        queue.push(anchor);
    }
    while (!queue.empty()) {
        const int c = queue.front();
        queue.pop();
        for (int n : adjacent[c])
            if (!seen[n]) {
                seen[n] = true;
                queue.push(n);
            }
    }
    std::vector<int> out;
    for (int c = 0; c < cameras; ++c)
        if (!seen[c]) out.push_back(c);
    return out;
}

RigSolution solve_rig(const std::vector<PinholeIntrinsics>& intrinsics,
                      const std::vector<Observation>& observations, const BoardSpec& board,
                      const RigSolveOptions& options) {
    options.check();
    board.check();
    const int n = static_cast<int>(intrinsics.size());
    RGBD_CHECK(options.anchor < n, "anchor " + std::to_string(options.anchor) +
                                       " is out of range (" + std::to_string(n) + " cameras)");
    for (const auto& o : observations) {
        RGBD_CHECK(o.sensor >= 0 && o.sensor < n, "observation of a camera out of range");
        RGBD_CHECK(o.board.ids.size() == o.board.pixels.size() && !o.board.ids.empty(),
                   "observation without corners");
    }
    RigSolution out;
    out.cameras.resize(n);
    for (const auto& o : observations) ++out.cameras[o.sensor].observations;
    out.unconnected = unconnected_cameras(n, observations, options.anchor);
    std::vector<bool> connected(n, true);
    for (int c : out.unconnected) connected[c] = false;
    for (int c = 0; c < n; ++c) out.cameras[c].connected = connected[c];

    // Frame sets seen by two or more connected cameras take part.
    const auto sets = by_frameset(observations);
    Problem problem{intrinsics, observations, board, {}, {}, {}, 0, 0};
    problem.board_of.assign(observations.size(), -1);
    std::vector<std::vector<int>> board_obs;  // board unknown -> observations
    for (const auto& [set, list] : sets) {
        std::vector<int> keep;
        for (int i : list)
            if (connected[observations[i].sensor]) keep.push_back(i);
        if (keep.size() < 2) continue;
        for (int i : keep) {
            problem.board_of[i] = problem.boards;
            problem.used.push_back(i);
            ++out.cameras[observations[i].sensor].linked;
        }
        board_obs.push_back(keep);
        ++problem.boards;
    }
    RGBD_CHECK_AS(AlgorithmError, out.cameras[options.anchor].linked > 0,
                  "the anchor camera never sees the board together with another camera");
    problem.camera_block.assign(n, -1);
    for (int c = 0; c < n; ++c)
        if (connected[c] && c != options.anchor && out.cameras[c].linked > 0)
            problem.camera_block[c] = problem.camera_blocks++;

    // Start: spanning tree from the anchor; each edge takes the frame set in which the two
    // cameras' PnP poses have the smallest summed reprojection RMS.
    std::vector<Pose> camera_from_anchor(n, Pose::Identity());
    std::vector<bool> placed(n, false);
    placed[options.anchor] = true;
    for (bool grew = true; grew;) {
        grew = false;
        // Best edge from a placed camera to an unplaced one, over all boards.
        double best = std::numeric_limits<double>::infinity();
        int best_from = -1, best_to = -1;
        for (const auto& list : board_obs)
            for (int a : list)
                for (int b : list) {
                    const int sa = observations[a].sensor, sb = observations[b].sensor;
                    if (!placed[sa] || placed[sb]) continue;
                    const double cost = observations[a].board.rms_px + observations[b].board.rms_px;
                    if (cost < best) {
                        best = cost;
                        best_from = a;
                        best_to = b;
                    }
                }
        if (best_from < 0) break;
        const auto& a = observations[best_from];
        const auto& b = observations[best_to];
        // camera_b_from_anchor = camera_b_from_board * board_from_camera_a * camera_a_from_anchor
        camera_from_anchor[b.sensor] = b.board.camera_from_board *
                                       a.board.camera_from_board.inverse() *
                                       camera_from_anchor[a.sensor];
        placed[b.sensor] = true;
        grew = true;
    }
    std::vector<Pose> anchor_from_board(problem.boards, Pose::Identity());
    for (int f = 0; f < problem.boards; ++f) {
        // From the observation with the lowest PnP RMS.
        int best = board_obs[f].front();
        for (int i : board_obs[f])
            if (observations[i].board.rms_px < observations[best].board.rms_px) best = i;
        anchor_from_board[f] = camera_from_anchor[observations[best].sensor].inverse() *
                               observations[best].board.camera_from_board;
    }

    const int unknowns = 6 * (problem.camera_blocks + problem.boards);
    const auto evaluate = [&](const std::vector<Pose>& cams, const std::vector<Pose>& boards,
                              double* sq_sum, int* count) {
        double cost = 0, sq = 0;
        int m = 0;
        for (int i : problem.used) {
            const auto& o = observations[i];
            for (std::size_t k = 0; k < o.board.ids.size(); ++k) {
                const double r =
                    residual(intrinsics[o.sensor], cams[o.sensor], boards[problem.board_of[i]],
                             board.corner(o.board.ids[k]), o.board.pixels[k], nullptr, nullptr)
                        .norm();
                cost += r <= options.huber_px ? 0.5 * r * r
                                              : options.huber_px * (r - 0.5 * options.huber_px);
                sq += r * r;
                ++m;
            }
        }
        if (sq_sum) *sq_sum = sq;
        if (count) *count = m;
        return cost;
    };
    double sq = 0;
    int m = 0;
    double cost = evaluate(camera_from_anchor, anchor_from_board, &sq, &m);
    out.residuals = m;
    out.initial_rms_px = m ? std::sqrt(sq / m) : 0.0;
    double lambda = 1e-4;
    for (int it = 0; it < options.max_iterations; ++it) {
        Eigen::MatrixXd h = Eigen::MatrixXd::Zero(unknowns, unknowns);
        Eigen::VectorXd g = Eigen::VectorXd::Zero(unknowns);
        for (int i : problem.used) {
            const auto& o = observations[i];
            const int cb = problem.camera_block[o.sensor];
            const int bb = problem.camera_blocks + problem.board_of[i];
            for (std::size_t k = 0; k < o.board.ids.size(); ++k) {
                Matrix26 jc, jb;
                const Eigen::Vector2d r =
                    residual(intrinsics[o.sensor], camera_from_anchor[o.sensor],
                             anchor_from_board[problem.board_of[i]], board.corner(o.board.ids[k]),
                             o.board.pixels[k], &jc, &jb);
                const double w = huber_weight(r.norm(), options.huber_px);
                h.block<6, 6>(6 * bb, 6 * bb) += w * jb.transpose() * jb;
                g.segment<6>(6 * bb) += w * jb.transpose() * r;
                if (cb >= 0) {
                    h.block<6, 6>(6 * cb, 6 * cb) += w * jc.transpose() * jc;
                    h.block<6, 6>(6 * cb, 6 * bb) += w * jc.transpose() * jb;
                    h.block<6, 6>(6 * bb, 6 * cb) += w * jb.transpose() * jc;
                    g.segment<6>(6 * cb) += w * jc.transpose() * r;
                }
            }
        }
        bool improved = false;
        for (int attempt = 0; attempt < 10 && !improved; ++attempt) {
            Eigen::MatrixXd damped = h;
            damped.diagonal() += lambda * h.diagonal().cwiseMax(1e-9);
            const Eigen::VectorXd delta = -damped.ldlt().solve(g);
            if (!delta.allFinite()) {
                lambda *= 10;
                continue;
            }
            std::vector<Pose> cams = camera_from_anchor;
            std::vector<Pose> boards = anchor_from_board;
            for (int c = 0; c < n; ++c)
                if (problem.camera_block[c] >= 0)
                    cams[c] = left_update(delta.segment<6>(6 * problem.camera_block[c]), cams[c]);
            for (int f = 0; f < problem.boards; ++f)
                boards[f] =
                    left_update(delta.segment<6>(6 * (problem.camera_blocks + f)), boards[f]);
            const double new_cost = evaluate(cams, boards, nullptr, nullptr);
            if (new_cost < cost) {
                const double gain = (cost - new_cost) / std::max(cost, 1e-300);
                camera_from_anchor = std::move(cams);
                anchor_from_board = std::move(boards);
                cost = new_cost;
                lambda = std::max(lambda / 10, 1e-9);
                improved = true;
                out.iterations = it + 1;
                if (gain < 1e-10) it = options.max_iterations;  // converged
            } else {
                lambda *= 10;
            }
        }
        if (!improved) break;
    }
    evaluate(camera_from_anchor, anchor_from_board, &sq, &m);
    out.final_rms_px = m ? std::sqrt(sq / m) : 0.0;
    out.boards = problem.boards;

    // Per-camera RMS and poses.
    std::vector<double> cam_sq(n, 0.0);
    std::vector<int> cam_count(n, 0);
    for (int i : problem.used) {
        const auto& o = observations[i];
        for (std::size_t k = 0; k < o.board.ids.size(); ++k) {
            const double r =
                residual(intrinsics[o.sensor], camera_from_anchor[o.sensor],
                         anchor_from_board[problem.board_of[i]], board.corner(o.board.ids[k]),
                         o.board.pixels[k], nullptr, nullptr)
                    .norm();
            cam_sq[o.sensor] += r * r;
            ++cam_count[o.sensor];
        }
    }
    for (int c = 0; c < n; ++c) {
        out.cameras[c].anchor_from_camera =
            connected[c] ? camera_from_anchor[c].inverse() : Pose::Identity();
        out.cameras[c].rms_px = cam_count[c] ? std::sqrt(cam_sq[c] / cam_count[c]) : 0.0;
    }
    return out;
}

}  // namespace rgbd::calibration
