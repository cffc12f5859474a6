// Waits for TBB task groups when a scope ends, for tasks that reference the scope's locals
// (rgbd::reconstruction's free-space and colour tasks, rgbd-reconstruct's evaluation).
#pragma once

#include <tbb/task_arena.h>
#include <tbb/task_group.h>

#include <initializer_list>
#include <vector>

namespace rgbd {

/// Waits for every group when destroyed. On the normal path the caller has waited already (and
/// got any task's exception from wait()); when an exception leaves the scope, the tasks are
/// still waited for, and their own exceptions are dropped for the one in flight.
class WaitAtExit {
public:
    /// `arena`: the arena the groups' tasks were run in (task_arena::execute), else null.
    WaitAtExit(std::initializer_list<tbb::task_group*> groups, tbb::task_arena* arena = nullptr)
        : groups_(groups), arena_(arena) {}
    WaitAtExit(const WaitAtExit&) = delete;
    WaitAtExit& operator=(const WaitAtExit&) = delete;
    ~WaitAtExit() {
        for (tbb::task_group* group : groups_) {
            try {
                if (arena_)
                    arena_->execute([group] { group->wait(); });
                else
                    group->wait();
            } catch (...) {
            }
        }
    }

private:
    std::vector<tbb::task_group*> groups_;
    tbb::task_arena* arena_ = nullptr;
};

}  // namespace rgbd
