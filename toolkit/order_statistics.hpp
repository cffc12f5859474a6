// Order statistics of samples: the value of a given rank by std::nth_element (linear time, no
// allocation; the values are reordered, which changes no later order statistic of them), and
// the medians and quantiles the toolkit uses, each with its exact rank convention so that
// results are reproducible to the bit.
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

namespace rgbd {

/// The value of rank k (0-based, k < values.size()) of `values`, which it reorders.
template <typename T>
T kth_smallest(std::vector<T>& values, std::size_t k) {
    const auto at = values.begin() + static_cast<std::ptrdiff_t>(k);
    std::nth_element(values.begin(), at, values.end());
    return *at;
}

/// The median as the value of rank n / 2: the upper of the two middle values for an even
/// count. Needs at least one value; reorders `values`.
template <typename T>
T upper_median(std::vector<T>& values) {
    return kth_smallest(values, values.size() / 2);
}

/// The median as the value of rank (n - 1) / 2: the lower of the two middle values for an
/// even count; 0 for no values. Reorders `values`.
inline double lower_median(std::vector<double>& values) {
    return values.empty() ? 0.0 : kth_smallest(values, (values.size() - 1) / 2);
}

/// The q-quantile (q in [0, 1]) as the value of rank floor(q (n - 1)): q = 0 the minimum, 1 the
/// maximum. Needs at least one value; reorders `values`.
inline double rank_quantile(std::vector<double>& values, double q) {
    return kth_smallest(values,
                        static_cast<std::size_t>(q * static_cast<double>(values.size() - 1)));
}

/// The q-quantile (q in [0, 1]) as the value of rank min(n - 1, floor(q n)). Needs at least
/// one value; reorders `values`.
inline double count_quantile(std::vector<double>& values, double q) {
    return kth_smallest(
        values, std::min(values.size() - 1, static_cast<std::size_t>(q * double(values.size()))));
}

}  // namespace rgbd
