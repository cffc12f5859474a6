#include "sensors/network/frame_grouper.hpp"

#include <algorithm>
#include <limits>

#include "toolkit/error.hpp"

namespace rgbd::sensors::net {

FrameGrouper::FrameGrouper(std::size_t sensors, std::int64_t tolerance_ns, bool complete_early)
    : queues_(sensors),
      tolerance_ns_(tolerance_ns),
      complete_early_(complete_early),
      formed_until_ns_(std::numeric_limits<std::int64_t>::min()) {
    RGBD_CHECK(sensors > 0, "frame grouper: no sensors");
    RGBD_CHECK(tolerance_ns >= 0, "frame grouper: tolerance must be >= 0");
}

bool FrameGrouper::add(std::size_t sensor, std::int64_t hub_ns, std::int64_t index) {
    RGBD_CHECK(sensor < queues_.size(), "frame grouper: sensor out of range");
    if (hub_ns <= formed_until_ns_) {
        ++late_;
        return false;
    }
    auto& q = queues_[sensor];
    // Frames of one sensor arrive in order: insertion is at the back almost always.
    auto it = q.end();
    while (it != q.begin() && std::prev(it)->hub_ns > hub_ns) --it;
    q.insert(it, Waiting{hub_ns, index});
    return true;
}

void FrameGrouper::form(std::int64_t horizon_ns, std::vector<io::FrameSet>& out) {
    for (;;) {
        std::int64_t t0 = std::numeric_limits<std::int64_t>::max();
        for (const auto& q : queues_)
            if (!q.empty()) t0 = std::min(t0, q.front().hub_ns);
        if (t0 == std::numeric_limits<std::int64_t>::max()) return;
        const std::int64_t window_end = t0 + tolerance_ns_;
        if (horizon_ns != std::numeric_limits<std::int64_t>::max() && window_end >= horizon_ns) {
            bool complete = complete_early_;
            for (const auto& q : queues_)
                complete = complete && !q.empty() && q.front().hub_ns <= window_end;
            if (!complete) return;
        }
        io::FrameSet set;
        set.set = next_set_++;
        set.frames.assign(queues_.size(), -1);
        std::int64_t lo = std::numeric_limits<std::int64_t>::max(), hi = lo, sum = 0, count = 0;
        hi = std::numeric_limits<std::int64_t>::min();
        for (std::size_t s = 0; s < queues_.size(); ++s) {
            auto& q = queues_[s];
            if (q.empty() || q.front().hub_ns > window_end) continue;
            set.frames[s] = q.front().index;
            lo = std::min(lo, q.front().hub_ns);
            hi = std::max(hi, q.front().hub_ns);
            sum += q.front().hub_ns - t0;
            ++count;
            q.pop_front();
        }
        set.time_ns = t0 + sum / count;
        set.spread_ns = hi - lo;
        formed_until_ns_ = std::max(formed_until_ns_, hi);
        out.push_back(std::move(set));
    }
}

}  // namespace rgbd::sensors::net
