#include "sensors/network/clock_sync.hpp"

#include <algorithm>
#include <cmath>

namespace rgbd::sensors::net {

void ClockEstimator::add_probe(const ProbeSample& s) {
    if (s.round_trip_ns() >= 0 && s.t3 >= s.t0) burst_.push_back(s);
}

bool ClockEstimator::end_burst() {
    if (burst_.empty()) return false;
    const ProbeSample best = *std::min_element(burst_.begin(), burst_.end(),
                                               [](const ProbeSample& a, const ProbeSample& b) {
                                                   return a.round_trip_ns() < b.round_trip_ns();
                                               });
    burst_.clear();
    last_rtt_ = best.round_trip_ns();
    max_rtt_ = std::max(max_rtt_, last_rtt_);
    kept_.push_back(
        {0.5 * (static_cast<double>(best.t0) + static_cast<double>(best.t3)), best.offset_ns()});
    while (kept_.size() > 2 && kept_.back().hub_mid - kept_.front().hub_mid > window_ns_)
        kept_.pop_front();
    refit();
    return true;
}

void ClockEstimator::refit() {
    const double n = static_cast<double>(kept_.size());
    double mean_t = 0, mean_y = 0;
    for (const Point& p : kept_) {
        mean_t += p.hub_mid;
        mean_y += p.theta;
    }
    mean_t /= n;
    mean_y /= n;
    double stt = 0, sty = 0;
    for (const Point& p : kept_) {
        stt += (p.hub_mid - mean_t) * (p.hub_mid - mean_t);
        sty += (p.hub_mid - mean_t) * (p.theta - mean_y);
    }
    fit_.ref = mean_t;
    fit_.intercept = mean_y;
    // A drift needs samples spread over about a second or more to be meaningful.
    fit_.slope = (kept_.size() >= 2 && stt > n * 0.25e18) ? sty / stt : 0.0;
}

std::int64_t ClockFit::to_hub(std::int64_t node_ns) const {
    // node = hub + a + b (hub - ref)  =>  hub = (node - a + b ref) / (1 + b)
    const double node = static_cast<double>(node_ns);
    return static_cast<std::int64_t>(
        std::llround((node - intercept + slope * ref) / (1.0 + slope)));
}

}  // namespace rgbd::sensors::net
