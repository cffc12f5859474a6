// Frame-set grouping by hub time (ALGORITHMS.md §1 step 4, DESIGN.md §5). Frames of all
// sensors wait in per-sensor queues ordered by hub time. A set is formed from the earliest
// waiting frame t0 of any sensor: it takes from every sensor its earliest waiting frame if
// that is within [t0, t0 + tolerance], else the sensor is missing (-1). So every set's spread
// (max - min hub time of its members) is <= tolerance, and no frame is used twice. A set is
// formed only once its window is older than the caller's horizon (now - latency), so frames
// still on their way can join. A frame older than the last formed window is "late": it is
// recorded but belongs to no set (counted).
#pragma once

#include <cstdint>
#include <deque>
#include <vector>

#include "io/capture_folder.hpp"

namespace rgbd::sensors::net {

class FrameGrouper {
public:
    /// `complete_early`: a window that already holds a frame of every sensor is formed at once,
    /// without waiting for the horizon (the same set, unless a sensor's earlier frame was still
    /// on its way: that one is then late). For live use (3D video), where latency counts.
    FrameGrouper(std::size_t sensors, std::int64_t tolerance_ns, bool complete_early = false);

    /// Queues frame `index` of sensor `sensor` (0-based, rig order) at hub time `hub_ns`.
    /// Returns false (and counts it late) when its window was already formed.
    bool add(std::size_t sensor, std::int64_t hub_ns, std::int64_t index);
    /// Forms every set whose window [t0, t0 + tolerance] ends before `horizon_ns` and appends
    /// them to `out` (set numbers continue from the previous call). Pass INT64_MAX to flush.
    void form(std::int64_t horizon_ns, std::vector<io::FrameSet>& out);

    std::int64_t late() const { return late_; }
    std::int64_t sets() const { return next_set_; }

private:
    struct Waiting {
        std::int64_t hub_ns;
        std::int64_t index;
    };
    std::vector<std::deque<Waiting>> queues_;
    std::int64_t tolerance_ns_;
    bool complete_early_;
    std::int64_t formed_until_ns_;  ///< frames at or before this time are late
    std::int64_t next_set_ = 0;
    std::int64_t late_ = 0;
};

}  // namespace rgbd::sensors::net
