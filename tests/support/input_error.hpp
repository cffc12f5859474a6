// Tests of error messages: a call that must throw InputError (or another Error), and what its
// message must name.
#pragma once

#include <gtest/gtest.h>

#include <initializer_list>
#include <string>

#include "toolkit/error.hpp"

namespace rgbd::test {

/// The message of the `Error` (InputError, IoError, ...) that `call()` throws; a test failure
/// (and "") when it throws none.
template <typename Error, typename Call>
std::string error_message(Call&& call) {
    try {
        call();
    } catch (const Error& e) {
        return e.what();
    }
    ADD_FAILURE() << "no " << ::testing::internal::GetTypeName<Error>();
    return "";
}

/// error_message<InputError>(call).
template <typename Call>
std::string input_error_message(Call&& call) {
    return error_message<InputError>(call);
}

/// Expects `call()` to throw an InputError whose message contains every one of `parts`, for
/// expect_input_error([&] { smooth_depth(cloud, {}); }, {"view 7", "organised"}).
template <typename Call>
void expect_input_error(Call&& call, std::initializer_list<std::string> parts) {
    const std::string message = input_error_message(call);
    for (const std::string& part : parts)
        EXPECT_NE(message.find(part), std::string::npos) << "'" << part << "' not in: " << message;
}

}  // namespace rgbd::test
