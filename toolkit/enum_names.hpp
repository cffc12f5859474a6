// Names of enum values: one constexpr table of {value, name} rows per enum serves both
// directions, to_string (name_of) and the parsers (value_of), so each name is written once.
//
//     constexpr EnumName<Verdict> kVerdictNames[] = {
//         {Verdict::kPass, "PASS"}, {Verdict::kWarn, "WARN"}, {Verdict::kFail, "FAIL"}};
//     const char* to_string(Verdict v) { return name_of(kVerdictNames, v); }
//
// A value may have several rows (aliases accepted by a parser): name_of returns the first.
#pragma once

#include <cstddef>
#include <optional>
#include <string_view>

namespace rgbd {

/// One row of an enum's name table.
template <typename E>
struct EnumName {
    E value;
    const char* name;
};

/// The name of the first row of `table` whose value is `value`; `otherwise` when none is.
template <typename E, std::size_t N>
constexpr const char* name_of(const EnumName<E> (&table)[N], E value, const char* otherwise = "?") {
    for (const EnumName<E>& row : table)
        if (row.value == value) return row.name;
    return otherwise;
}

/// The value of the first row of `table` named exactly `name`; nullopt when none is.
template <typename E, std::size_t N>
constexpr std::optional<E> value_of(const EnumName<E> (&table)[N], std::string_view name) {
    for (const EnumName<E>& row : table)
        if (name == row.name) return row.value;
    return std::nullopt;
}

}  // namespace rgbd
