#include "toolkit/error.hpp"

#include <charconv>
#include <cmath>
#include <cstdlib>
#include <system_error>

namespace rgbd {

bool Range::contains(double value) const {
    if (!std::isfinite(value)) return false;
    const bool above = lower == Bound::kClosed ? value >= lo : value > lo;
    const bool below = upper == Bound::kClosed ? value <= hi : value < hi;
    return above && below;
}

std::string Range::to_string() const {
    std::string text(1, lower == Bound::kClosed ? '[' : '(');
    text += format_number(lo);
    text += ", ";
    text += format_number(hi);
    text += upper == Bound::kClosed ? ']' : ')';
    return text;
}

std::string format_number(double value) {
    char buffer[64];
    // Shortest round-trip digits in scientific notation first, for the decimal exponent.
    const auto sci =
        std::to_chars(buffer, buffer + sizeof buffer, value, std::chars_format::scientific);
    const std::string text(buffer, sci.ptr);
    const std::size_t e = text.find('e');
    if (e == std::string::npos) return text;  // inf, nan
    const int exponent = std::atoi(text.c_str() + e + 1);
    if (exponent >= -4 && exponent <= 5) {
        const auto fixed =
            std::to_chars(buffer, buffer + sizeof buffer, value, std::chars_format::fixed);
        return std::string(buffer, fixed.ptr);
    }
    return text.substr(0, e + 1) + std::to_string(exponent);
}

namespace detail {

void throw_out_of_range(std::string_view what, const Range& range, std::string_view unit,
                        const std::string& got) {
    std::string message(what);
    message += " must be in " + range.to_string();
    if (!unit.empty()) (message += ' ') += unit;
    throw InputError(message + ", got " + got);
}

}  // namespace detail
}  // namespace rgbd
