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
    kept_.push_back({0.5 * (static_cast<double>(best.t0) + static_cast<double>(best.t3)),
                     best.offset_ns(), static_cast<double>(best.round_trip_ns())});
    while (kept_.size() > 2 && kept_.back().hub_mid - kept_.front().hub_mid > window_ns_)
        kept_.pop_front();
    refit();
    return true;
}

void ClockEstimator::refit() {
    // Weighted least squares, weight 1 / rtt^2: a sample's offset error is bounded by half its
    // round trip, so a burst whose best probe still queued (a loaded machine, all nodes sending
    // a frame at once) counts little against the clean ones (floor 50 us: loopback jitter).
    double sw = 0, mean_t = 0, mean_y = 0;
    for (const Point& p : kept_) {
        const double w = weight(p);
        sw += w;
        mean_t += w * p.hub_mid;
        mean_y += w * p.theta;
    }
    mean_t /= sw;
    mean_y /= sw;
    double stt = 0, sty = 0, span_lo = kept_.front().hub_mid, span_hi = span_lo;
    for (const Point& p : kept_) {
        const double w = weight(p);
        stt += w * (p.hub_mid - mean_t) * (p.hub_mid - mean_t);
        sty += w * (p.hub_mid - mean_t) * (p.theta - mean_y);
        span_lo = std::min(span_lo, p.hub_mid);
        span_hi = std::max(span_hi, p.hub_mid);
    }
    fit_.ref = mean_t;
    fit_.intercept = mean_y;
    // A drift needs samples spread over about a second or more to be meaningful.
    fit_.slope = (kept_.size() >= 2 && span_hi - span_lo > 1e9 && stt > 0) ? sty / stt : 0.0;
}

double ClockEstimator::weight(const Point& p) {
    const double rtt = std::max(p.rtt, 50'000.0);
    return 1.0 / (rtt * rtt);
}

std::int64_t ClockFit::to_hub(std::int64_t node_ns) const {
    // node = hub + a + b (hub - ref)  =>  hub = (node - a + b ref) / (1 + b)
    const double node = static_cast<double>(node_ns);
    return static_cast<std::int64_t>(
        std::llround((node - intercept + slope * ref) / (1.0 + slope)));
}

}  // namespace rgbd::sensors::net
