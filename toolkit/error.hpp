// Error types of the toolkit. Library code throws these; tools catch them in cli/common
// and turn them into one-line messages and exit codes (cli/README.md).
#pragma once

#include <stdexcept>
#include <string>

namespace rgbd {

/// Base of every error the toolkit throws on purpose.
class Error : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

/// Bad input: malformed files, invalid parameters, NaN where data must be finite.
class InputError : public Error {
public:
    using Error::Error;
};

/// The file system or a stream failed (cannot open, cannot write, short write).
class IoError : public Error {
public:
    using Error::Error;
};

/// An algorithm could not produce a result for a reason other than bad input.
class AlgorithmError : public Error {
public:
    using Error::Error;
};

}  // namespace rgbd

/// Validate a condition; throws rgbd::InputError with the message when it does not hold.
/// Use for everything a release build must still check (CGAL preconditions vanish there).
#define RGBD_CHECK(cond, message)                       \
    do {                                                \
        if (!(cond)) throw ::rgbd::InputError(message); \
    } while (0)

/// Same as RGBD_CHECK with an explicit exception type.
#define RGBD_CHECK_AS(ExceptionType, cond, message) \
    do {                                            \
        if (!(cond)) throw ExceptionType(message);  \
    } while (0)
