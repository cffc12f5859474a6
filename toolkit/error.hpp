// Error types of the toolkit. Library code throws these; tools catch them in cli/common
// and turn them into one-line messages and exit codes (cli/README.md).
#pragma once

#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>

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

/// Whether an end of a Range belongs to it.
enum class Bound { kClosed, kOpen };

/// An interval of allowed parameter values with finite ends, each closed or open:
/// Range::closed(0, 1000) is [0, 1000], Range::open_closed(0, 89) is (0, 89].
struct Range {
    double lo = 0.0;
    double hi = 0.0;
    Bound lower = Bound::kClosed;
    Bound upper = Bound::kClosed;

    static constexpr Range closed(double lo, double hi) {
        return {lo, hi, Bound::kClosed, Bound::kClosed};
    }
    static constexpr Range open(double lo, double hi) {
        return {lo, hi, Bound::kOpen, Bound::kOpen};
    }
    static constexpr Range open_closed(double lo, double hi) {
        return {lo, hi, Bound::kOpen, Bound::kClosed};
    }
    static constexpr Range closed_open(double lo, double hi) {
        return {lo, hi, Bound::kClosed, Bound::kOpen};
    }

    /// Whether `value` lies in the range; false for NaN and for +-infinity.
    bool contains(double value) const;
    /// The range as a message writes it: "[0, 1000]", "(0, 89]", "(0, 1e4)" (numbers as
    /// format_number writes them).
    std::string to_string() const;
};

/// A number as messages write it: the shortest text that reads back as the same double, in
/// fixed notation for exponents -4..5 ("1000", "0.005", "100000") and scientific with a bare
/// exponent otherwise ("1e6", "3.6e6", "1e-6"), like printf's %g without its 6-digit rounding.
std::string format_number(double value);

namespace detail {
/// Throws InputError "<what> must be in <range>[ <unit>], got <got>".
[[noreturn]] void throw_out_of_range(std::string_view what, const Range& range,
                                     std::string_view unit, const std::string& got);
}  // namespace detail

/// The range check of an options field: throws InputError
/// "<what> must be in <range>[ <unit>], got <value>" unless `value` lies in `range` (NaN and
/// infinities never do), for check_range("distance outliers: alpha", alpha, Range::closed(0,
/// 1000)) -> "distance outliers: alpha must be in [0, 1000], got 1500". `unit` (may be empty)
/// follows the range after a space: "degrees", "m", "x spacing".
inline void check_range(std::string_view what, double value, const Range& range,
                        std::string_view unit = {}) {
    if (!range.contains(value)) detail::throw_out_of_range(what, range, unit, format_number(value));
}

/// The same for an integer field; the message gives the value exactly ("got 5000").
template <typename Int, std::enable_if_t<std::is_integral_v<Int>, int> = 0>
void check_range(std::string_view what, Int value, const Range& range, std::string_view unit = {}) {
    if (!range.contains(static_cast<double>(value)))
        detail::throw_out_of_range(what, range, unit, std::to_string(value));
}

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
