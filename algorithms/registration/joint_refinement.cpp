// Joint multi-view point-to-plane refinement on per-view kd-trees (see align_stages.hpp).
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "algorithms/internal/icp_math.hpp"
#include "algorithms/registration/align_stages.hpp"

namespace rgbd::registration::detail {

namespace {

constexpr std::size_t kChunk = 512;
constexpr std::uint64_t kNoHint = ~std::uint64_t{0};

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

/// One view's share of the joint normal equations: its own block, and per partner slot the
/// cross block (view, partner), the partner's block and the partner's gradient.
struct ViewSums {
    Mat6 h_self = Mat6::Zero();
    Vec6 g_self = Vec6::Zero();
    std::vector<Mat6> h_cross, h_other;
    std::vector<Vec6> g_other;
    std::vector<char> used;
    double extent = 0.0;  // largest distance of the view's points from the centre
};

}  // namespace

std::vector<std::vector<std::size_t>> partner_views(std::size_t nv,
                                                    const std::vector<PairAlignment>& pairs,
                                                    int hops) {
    std::vector<std::vector<std::size_t>> out(nv);
    if (pairs.empty()) {
        for (std::size_t v = 0; v < nv; ++v)
            for (std::size_t u = 0; u < nv; ++u)
                if (u != v) out[v].push_back(u);
        return out;
    }
    std::vector<std::vector<std::size_t>> adj(nv);
    for (const PairAlignment& p : pairs) {
        adj[p.target].push_back(p.source);
        adj[p.source].push_back(p.target);
    }
    for (std::size_t v = 0; v < nv; ++v) {
        std::set<std::size_t> reach{v};
        std::vector<std::size_t> frontier{v};
        for (int h = 0; h < hops && !frontier.empty(); ++h) {
            std::vector<std::size_t> next;
            for (std::size_t a : frontier)
                for (std::size_t b : adj[a])
                    if (reach.insert(b).second) next.push_back(b);
            frontier.swap(next);
        }
        reach.erase(v);
        out[v].assign(reach.begin(), reach.end());
    }
    return out;
}

JointRefinement::JointRefinement(std::vector<Working>& work,
                                 std::vector<std::vector<std::size_t>> partners,
                                 const JointSettings& settings)
    : work_(work), partners_(std::move(partners)), s_(settings) {
    const std::size_t nv = work_.size();
    offset_.assign(nv + 1, 0);
    for (std::size_t v = 0; v < nv; ++v) offset_[v + 1] = offset_[v] + work_[v].reg.xyz.size();
    match_.assign(offset_[nv], Match{});
    hint_.assign(offset_[nv], kNoHint);
    matched_.assign(nv, 0);
    sq_sum_.assign(nv, 0.0);
}

void JointRefinement::match(double dmax, std::size_t stride) {
    const std::size_t nv = work_.size();
    // Relative placement of every partner's working frame: partner_from_view.
    std::vector<std::vector<Pose>> rel(nv);
    for (std::size_t v = 0; v < nv; ++v)
        for (std::size_t u : partners_[v])
            rel[v].push_back(Pose(work_[u].pose.inverse() * work_[v].pose));
    // Tasks: fixed chunks of each view's points (the outcome does not depend on the threads).
    std::vector<std::pair<std::size_t, std::size_t>> tasks;  // (view, first point)
    for (std::size_t v = 0; v < nv; ++v)
        for (std::size_t i = 0; i < work_[v].reg.xyz.size(); i += kChunk) tasks.emplace_back(v, i);
    const double max_sq = dmax * dmax;
    tbb::parallel_for(std::size_t{0}, tasks.size(), [&](std::size_t t) {
        const auto [v, first] = tasks[t];
        const internal::RegCloud& reg = work_[v].reg;
        const std::vector<std::size_t>& part = partners_[v];
        const std::size_t end = std::min(reg.xyz.size(), first + kChunk);
        for (std::size_t i = first; i < end; ++i) {
            const std::size_t a = offset_[v] + i;
            Match m;
            if (stride > 1 && i % stride != 0) {
                match_[a] = m;
                continue;
            }
            double bound = max_sq;
            // The previous match bounds the nearest distance: much smaller searches.
            std::size_t hinted = part.size();
            if (hint_[a] != kNoHint) {
                const std::size_t u = hint_[a] >> 32;
                const std::uint32_t j = static_cast<std::uint32_t>(hint_[a] & 0xffffffffu);
                const auto it = std::lower_bound(part.begin(), part.end(), u);
                if (it != part.end() && *it == u) {
                    hinted = static_cast<std::size_t>(it - part.begin());
                    const double dh =
                        (rel[v][hinted] * reg.xyz[i] - work_[u].reg.xyz[j]).squaredNorm();
                    if (dh < bound) bound = dh * (1.0 + 1e-9) + 1e-300;
                }
            }
            for (std::size_t k = 0; k < part.size(); ++k) {
                // The hinted partner first: its match tightens the bound for the others.
                std::size_t s = k;
                if (hinted < part.size()) s = k == 0 ? hinted : (k - 1 < hinted ? k - 1 : k);
                const std::size_t u = part[s];
                std::uint32_t j;
                double d2;
                if (!work_[u].tree->nearest_within(rel[v][s] * reg.xyz[i], bound, j, d2)) continue;
                if (m.view >= 0 && d2 >= m.sq_dist) continue;
                m.view = static_cast<std::int32_t>(u);
                m.index = j;
                m.sq_dist = d2;
                bound = d2 * (1.0 + 1e-9) + 1e-300;
            }
            hint_[a] = m.view >= 0 ? (std::uint64_t(m.view) << 32) | m.index : kNoHint;
            if (m.view >= 0 && m.sq_dist > max_sq) m.view = -1;
            if (m.view >= 0 && s_.cos_gate > -1.5) {
                // The nearest partner point decides: no second choice past a failed gate.
                const std::size_t s = static_cast<std::size_t>(
                    std::lower_bound(part.begin(), part.end(), std::size_t(m.view)) - part.begin());
                const double cosang =
                    (rel[v][s].linear() * reg.normals[i]).dot(work_[m.view].reg.normals[m.index]);
                if ((s_.oriented ? cosang : std::abs(cosang)) < s_.cos_gate) m.view = -1;
            }
            match_[a] = m;
        }
    });
    sampled_ = 0;
    const std::size_t every = std::max<std::size_t>(stride, 1);
    for (std::size_t v = 0; v < nv; ++v) {
        sampled_ += (work_[v].reg.xyz.size() + every - 1) / every;
        matched_[v] = 0;
        sq_sum_[v] = 0.0;
        for (std::size_t a = offset_[v]; a < offset_[v + 1]; ++a) {
            if (match_[a].view < 0) continue;
            ++matched_[v];
            sq_sum_[v] += match_[a].sq_dist;
        }
    }
}

double JointRefinement::overlap() const {
    std::size_t m = 0;
    for (std::size_t x : matched_) m += x;
    return static_cast<double>(m) / static_cast<double>(std::max<std::size_t>(sampled_, 1));
}

double JointRefinement::rms() const {
    std::size_t m = 0;
    double sum = 0.0;
    for (std::size_t v = 0; v < matched_.size(); ++v) {
        m += matched_[v];
        sum += sq_sum_[v];
    }
    return m ? std::sqrt(sum / static_cast<double>(m)) : 0.0;
}

std::optional<double> JointRefinement::step(double dmax, std::size_t min_matches,
                                            std::vector<int>& moved) {
    const std::size_t nv = work_.size();
    const double k = s_.kernel_scale * dmax;
    // Global centre of the working points for the rotation parametrisation (conditioning).
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (const Working& w : work_)
        centre += static_cast<double>(w.reg.xyz.size()) * (w.pose * w.reg.centroid);
    centre /= static_cast<double>(std::max<std::size_t>(match_.size(), 1));

    std::vector<ViewSums> sums(nv);
    tbb::parallel_for(std::size_t{0}, nv, [&](std::size_t v) {
        ViewSums& vs = sums[v];
        const std::size_t np = partners_[v].size();
        vs.h_cross.assign(np, Mat6::Zero());
        vs.h_other.assign(np, Mat6::Zero());
        vs.g_other.assign(np, Vec6::Zero());
        vs.used.assign(np, 0);
        const Working& w = work_[v];
        for (std::size_t i = 0; i < w.reg.xyz.size(); ++i) {
            const Eigen::Vector3d p = w.pose * w.reg.xyz[i];
            vs.extent = std::max(vs.extent, (p - centre).norm());
            const Match& m = match_[offset_[v] + i];
            if (m.view < 0) continue;
            const std::size_t u = static_cast<std::size_t>(m.view);
            const std::size_t s = static_cast<std::size_t>(
                std::lower_bound(partners_[v].begin(), partners_[v].end(), u) -
                partners_[v].begin());
            const Working& o = work_[u];
            const Eigen::Vector3d q = o.pose * o.reg.xyz[m.index];
            const Eigen::Vector3d n = o.pose.linear() * o.reg.normals[m.index];
            const double r = (p - q).dot(n);
            const double wt = internal::robust_weight(s_.kernel, r, k);
            if (wt <= 0) continue;
            vs.used[s] = 1;
            // One residual r_w along direction `dir` with weight `weight`: its Jacobians for
            // this view (ji) and the partner (jj) into both views' normal equations.
            Vec6 ji, jj;
            const auto add_term = [&](const Eigen::Vector3d& dir, double weight, double r_w) {
                ji.head<3>() = (p - centre).cross(dir);
                ji.tail<3>() = dir;
                jj.head<3>() = -(q - centre).cross(dir);
                jj.tail<3>() = -dir;
                vs.h_self.noalias() += weight * ji * ji.transpose();
                vs.h_other[s].noalias() += weight * jj * jj.transpose();
                vs.h_cross[s].noalias() += weight * ji * jj.transpose();
                vs.g_self += (weight * r_w) * ji;
                vs.g_other[s] += (weight * r_w) * jj;
            };
            add_term(n, wt, r);
            if (!s_.colour) continue;
            // Park et al.'s colour term, in the same units as the geometric one.
            const Eigen::Vector3d d = o.pose.linear() * o.reg.gradient[m.index];
            const double rc = o.reg.intensity[m.index] + d.dot(p - q) - w.reg.intensity[i];
            const double wc =
                wt * s_.colour_scale * internal::robust_weight(1, rc, 2.0 * s_.colour_sigma);
            add_term(d, wc, rc);
        }
    });

    // Free views: all but the gauge and those with too few matches this iteration.
    std::vector<std::ptrdiff_t> slot(nv, -1);
    std::vector<std::size_t> active;
    for (std::size_t v = 0; v < nv; ++v)
        if (v != s_.fixed_view && matched_[v] >= min_matches) {
            slot[v] = static_cast<std::ptrdiff_t>(active.size());
            active.push_back(v);
        }
    if (active.empty()) return std::nullopt;
    const Eigen::Index m = static_cast<Eigen::Index>(6 * active.size());
    // Block accumulation in view order (deterministic), then the sparse matrix.
    std::vector<Mat6> diag(nv, Mat6::Zero());
    Eigen::VectorXd g = Eigen::VectorXd::Zero(m);
    std::map<std::pair<std::size_t, std::size_t>, Mat6> off;
    for (std::size_t v = 0; v < nv; ++v) {
        const ViewSums& vs = sums[v];
        diag[v] += vs.h_self;
        if (slot[v] >= 0) g.segment<6>(6 * slot[v]) += vs.g_self;
        for (std::size_t s = 0; s < partners_[v].size(); ++s) {
            if (!vs.used[s]) continue;
            const std::size_t u = partners_[v][s];
            diag[u] += vs.h_other[s];
            if (slot[u] >= 0) g.segment<6>(6 * slot[u]) += vs.g_other[s];
            if (slot[v] < 0 || slot[u] < 0) continue;
            // Lower-triangular storage: block (row, col) with row > col.
            if (slot[v] > slot[u]) {
                auto [it, fresh] = off.try_emplace({v, u}, Mat6::Zero());
                it->second += vs.h_cross[s];
            } else {
                auto [it, fresh] = off.try_emplace({u, v}, Mat6::Zero());
                it->second += vs.h_cross[s].transpose();
            }
        }
    }
    // The calibration prior: the view's correction from its initial pose, about the centre
    // (first order: a step x changes it by x).
    if (s_.prior.any())
        for (std::size_t v : active) {
            const Pose d = work_[v].pose * work_[v].initial.inverse();
            const Eigen::AngleAxisd aa(d.linear());
            Vec6 delta;
            delta.head<3>() = aa.angle() * aa.axis();
            delta.tail<3>() = d * centre - centre;
            diag[v].diagonal() += s_.prior;
            g.segment<6>(6 * slot[v]) += s_.prior.cwiseProduct(delta);
        }
    double max_diag = 1e-300;
    for (std::size_t v : active) max_diag = std::max(max_diag, diag[v].diagonal().maxCoeff());
    const double damping = 1e-9 * max_diag;  // tiny Levenberg damping (symmetric slides)
    std::vector<Eigen::Triplet<double>> trip;
    trip.reserve(36 * (active.size() + 2 * off.size()));
    for (std::size_t v : active) {
        const Eigen::Index o = 6 * slot[v];
        for (int r = 0; r < 6; ++r)
            for (int c = 0; c <= r; ++c)
                trip.emplace_back(o + r, o + c, diag[v](r, c) + (r == c ? damping : 0.0));
    }
    for (const auto& [key, b] : off) {
        const Eigen::Index ro = 6 * slot[key.first], co = 6 * slot[key.second];
        for (int r = 0; r < 6; ++r)
            for (int c = 0; c < 6; ++c) trip.emplace_back(ro + r, co + c, b(r, c));
    }
    Eigen::SparseMatrix<double> h(m, m);
    h.setFromTriplets(trip.begin(), trip.end());
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower> ldlt(h);
    if (ldlt.info() != Eigen::Success) return std::nullopt;
    const Eigen::VectorXd x = ldlt.solve(-g);
    if (ldlt.info() != Eigen::Success || !x.allFinite()) return std::nullopt;

    // Largest displacement of any working point by this step (bound).
    double max_motion = 0;
    for (std::size_t a = 0; a < active.size(); ++a) {
        const Vec6 st = x.segment<6>(6 * a);
        Working& w = work_[active[a]];
        w.pose = orthonormalized(internal::rigid_update(st, centre) * w.pose);
        ++moved[active[a]];
        max_motion = std::max(max_motion,
                              st.head<3>().norm() * sums[active[a]].extent + st.tail<3>().norm());
    }
    return max_motion;
}

}  // namespace rgbd::registration::detail
