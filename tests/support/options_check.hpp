// Tests of the options structs' check(): default options with one field changed.
#pragma once

#include "toolkit/error.hpp"

namespace rgbd::test {

/// Whether check() rejects (InputError) default `Options` after `change(options)`, for
/// EXPECT_TRUE(rejects<DistanceOptions>([](auto& o) { o.alpha = -1; })).
template <typename Options, typename Change>
bool rejects(Change&& change) {
    Options options;
    change(options);
    try {
        options.check();
    } catch (const InputError&) {
        return true;
    }
    return false;
}

}  // namespace rgbd::test
