// Node clock -> hub clock (docs/algorithms.md §1 steps 1-2): NTP/Cristian four-timestamp probes.
// The hub sends a probe at hub time t0, the node stamps receipt t1 and reply t2 in its clock,
// the hub receives the reply at t3. Per sample offset theta = ((t1 - t0) + (t2 - t3)) / 2 and
// round trip delta = (t3 - t0) - (t2 - t1). Of each burst of probes the sample with the
// smallest delta (least queueing) is kept; the kept samples of the last `window_s` seconds are
// fitted by least squares with theta(t) = a + b (t - t_ref) (b = drift), each weighted by
// 1 / rtt^2 (its offset error is bounded by rtt / 2), and node stamps are mapped through the
// fit, not through the last probe.
#pragma once

#include <cstdint>
#include <deque>
#include <vector>

namespace rgbd::sensors::net {

/// One four-timestamp exchange: t0, t3 hub clock; t1, t2 node clock (ns).
struct ProbeSample {
    std::int64_t t0 = 0, t1 = 0, t2 = 0, t3 = 0;
    std::int64_t round_trip_ns() const { return (t3 - t0) - (t2 - t1); }
    /// node clock - hub clock at the probe's midpoint, ns
    double offset_ns() const {
        return 0.5 * (static_cast<double>(t1 - t0) + static_cast<double>(t2 - t3));
    }
};

/// The fitted model theta(t) = intercept + slope (t - ref): a small value to copy around.
struct ClockFit {
    double ref = 0, intercept = 0, slope = 0;
    /// Estimated offset node - hub (ns) at hub time `hub_ns`.
    double offset_ns_at(std::int64_t hub_ns) const {
        return intercept + slope * (static_cast<double>(hub_ns) - ref);
    }
    /// Maps a node clock stamp to hub time.
    std::int64_t to_hub(std::int64_t node_ns) const;
};

class ClockEstimator {
public:
    /// `window_s`: fit over kept samples of this many seconds (hub time) before the newest.
    explicit ClockEstimator(double window_s = 60.0) : window_ns_(window_s * 1e9) {}

    /// Adds a sample to the current burst (samples with a negative round trip are ignored).
    void add_probe(const ProbeSample& sample);
    /// Ends the burst: keeps its smallest-round-trip sample and refits. Returns false when the
    /// burst had no usable sample.
    bool end_burst();
    /// At least one burst was kept.
    bool ready() const { return !kept_.empty(); }
    /// Kept bursts.
    std::size_t bursts() const { return kept_.size(); }

    /// Estimated offset node - hub (ns) at hub time `hub_ns`.
    double offset_ns_at(std::int64_t hub_ns) const { return fit_.offset_ns_at(hub_ns); }
    /// Estimated drift of the node clock against the hub clock, parts per million.
    double drift_ppm() const { return fit_.slope * 1e6; }
    /// Maps a node clock stamp to hub time through the fit.
    std::int64_t to_hub(std::int64_t node_ns) const { return fit_.to_hub(node_ns); }
    const ClockFit& fit() const { return fit_; }
    /// Round trip of the last kept sample (ns).
    std::int64_t last_round_trip_ns() const { return last_rtt_; }
    /// Largest round trip of any kept sample so far (ns). A kept sample's offset is within
    /// half its round trip of the true offset (the two one-way delays are unknown but not
    /// negative), so this bounds the error of every sample the fits were made of.
    std::int64_t max_round_trip_ns() const { return max_rtt_; }

private:
    struct Point {
        double hub_mid;  ///< (t0 + t3) / 2
        double theta;
        double rtt;  ///< round trip of the kept sample, ns
    };
    void refit();
    static double weight(const Point& p);
    double window_ns_;
    std::vector<ProbeSample> burst_;
    std::deque<Point> kept_;
    ClockFit fit_;
    std::int64_t last_rtt_ = 0;
    std::int64_t max_rtt_ = 0;
};

}  // namespace rgbd::sensors::net
