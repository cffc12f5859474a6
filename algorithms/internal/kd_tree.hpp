// kd-tree over a contiguous array of 3D points (nanoflann), for kNN and radius queries in
// hot loops. Internal to algorithms/: public headers never expose it.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <nanoflann.hpp>
#include <utility>
#include <vector>

namespace rgbd::internal {

/// nanoflann's dataset interface over a borrowed vector of fixed-size points (Eigen vectors,
/// std::arrays) with coordinates of type Scalar; no bounding box (nanoflann computes it).
template <typename Point, typename Scalar>
struct VectorAdaptor {
    const std::vector<Point>* points;
    std::size_t kdtree_get_point_count() const { return points->size(); }
    Scalar kdtree_get_pt(std::size_t i, std::size_t d) const { return (*points)[i][d]; }
    template <class Box>
    bool kdtree_get_bbox(Box&) const {
        return false;
    }
};

/// Borrowed view of points; the array must outlive the tree.
class KdTree {
public:
    explicit KdTree(const std::vector<Eigen::Vector3d>& points, int leaf_size = 16)
        : adaptor_{&points},
          index_(3, adaptor_, nanoflann::KDTreeSingleIndexAdaptorParams(leaf_size)) {
        if (!points.empty()) index_.buildIndex();
    }
    /// A temporary would be destroyed while the tree still points into it.
    explicit KdTree(std::vector<Eigen::Vector3d>&&, int leaf_size = 16) = delete;

    std::size_t size() const { return adaptor_.points->size(); }

    /// k nearest neighbours of q (q itself included if it is in the tree). Returns the count
    /// found (<= k); indices and squared distances are written to the caller's buffers.
    std::size_t knn(const Eigen::Vector3d& q, std::size_t k, std::uint32_t* indices,
                    double* sq_dists) const {
        if (size() == 0 || k == 0) return 0;
        nanoflann::KNNResultSet<double, std::uint32_t> result(k);
        result.init(indices, sq_dists);
        index_.findNeighbors(result, q.data(), nanoflann::SearchParams());
        return result.size();
    }

    /// Nearest neighbour; returns false on an empty tree.
    bool nearest(const Eigen::Vector3d& q, std::uint32_t& index, double& sq_dist) const {
        return knn(q, 1, &index, &sq_dist) == 1;
    }

    /// Nearest neighbour no farther than sqrt(max_sq): the search starts with that bound, so
    /// branches beyond it are never visited (ICP matching with a correspondence distance).
    bool nearest_within(const Eigen::Vector3d& q, double max_sq, std::uint32_t& index,
                        double& sq_dist) const {
        if (size() == 0) return false;
        Nearest result(max_sq);
        index_.findNeighbors(result, q.data(), nanoflann::SearchParams());
        if (!result.found) return false;
        index = result.index;
        sq_dist = result.dist;
        return true;
    }

    /// All points within `radius` (not squared) of q, sorted by distance unless `sorted` is
    /// false (then in tree order: cheaper when the caller does not need the order). `out` is
    /// reused.
    std::size_t radius(const Eigen::Vector3d& q, double radius,
                       std::vector<std::pair<std::uint32_t, double>>& out,
                       bool sorted = true) const {
        out.clear();
        if (size() == 0) return 0;
        nanoflann::SearchParams params;
        params.sorted = sorted;
        return index_.radiusSearch(q.data(), radius * radius, out, params);
    }

private:
    /// nanoflann result set for one neighbour within a bound.
    struct Nearest {
        explicit Nearest(double bound) : dist(bound) {}
        double dist;
        std::uint32_t index = 0;
        bool found = false;
        std::size_t size() const { return found ? 1 : 0; }
        bool full() const { return true; }
        bool addPoint(double d, std::uint32_t i) {
            if (d < dist) {
                dist = d;
                index = i;
                found = true;
            }
            return true;
        }
        double worstDist() const { return dist; }
    };
    using Adaptor = VectorAdaptor<Eigen::Vector3d, double>;
    using Index = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, Adaptor>,
                                                      Adaptor, 3, std::uint32_t>;
    Adaptor adaptor_;
    Index index_;
};

}  // namespace rgbd::internal
