// Which command-line option an error message is about. Library checks name the field of their
// options struct ("depth window z_min_m must be >= 0") or quote the refused value ("unknown
// noise model 'bogus'", check_range's "... got 1e300"), not the option a user typed; a tool's
// driver appends the option this finds.
#pragma once

#include <string>
#include <vector>

namespace rgbd {

/// An option given with a value on a command line, as option_named_by() compares it.
struct GivenOption {
    std::string name;  ///< without dashes: "std-ratio"
    /// Its value as a message would quote it: a text as typed, a number as format_number
    /// writes it (check_range's "got <number>"); empty for a value of another kind.
    std::string text;
};

/// The option `message` is about, as " (--name)", when the message does not name one itself
/// (it holds no "--"). Of the `given` options, the first of these rules that fits exactly one:
/// the option whose value the message quotes (in single quotes, or after "got");
/// whose name written with underscores is a field name of the message (std-ratio: std_ratio);
/// is a word of it (alpha); matches a field name up to a '_' (z-min: z_min_m; theta-max-deg:
/// theta_max). "" when none fits or several do.
std::string option_named_by(const std::string& message, const std::vector<GivenOption>& given);

}  // namespace rgbd
