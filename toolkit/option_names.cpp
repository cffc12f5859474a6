#include "toolkit/option_names.hpp"

#include <algorithm>
#include <cctype>

namespace rgbd {

namespace {

/// Whether `message` says "got <value>" with nothing alphanumeric or '.' right after it (so
/// "got 1" is not found in "got 10" or "got 1.5").
bool quotes_number(const std::string& message, const std::string& number) {
    const std::string quoted = "got " + number;
    for (std::size_t at = message.find(quoted); at != std::string::npos;
         at = message.find(quoted, at + 1)) {
        const std::size_t end = at + quoted.size();
        if (end == message.size() ||
            !(std::isalnum(static_cast<unsigned char>(message[end])) || message[end] == '.'))
            return true;
    }
    return false;
}

/// The message's words (letters, digits and '_': field names have '_').
std::vector<std::string> identifiers_of(const std::string& message) {
    std::vector<std::string> identifiers;
    for (std::size_t i = 0; i < message.size();) {
        std::size_t j = i;
        while (j < message.size() &&
               (std::isalnum(static_cast<unsigned char>(message[j])) || message[j] == '_'))
            ++j;
        if (j > i) identifiers.push_back(message.substr(i, j - i));
        i = std::max(j, i + 1);
    }
    return identifiers;
}

bool up_to_underscore(const std::string& longer, const std::string& shorter) {
    return longer.size() > shorter.size() && longer.compare(0, shorter.size(), shorter) == 0 &&
           longer[shorter.size()] == '_';
}

}  // namespace

std::string option_named_by(const std::string& message, const std::vector<GivenOption>& given) {
    if (message.find("--") != std::string::npos) return "";
    const std::vector<std::string> identifiers = identifiers_of(message);
    std::vector<std::string> by_value, by_field, by_word, by_prefix;
    for (const GivenOption& option : given) {
        if (!option.text.empty() && (message.find("'" + option.text + "'") != std::string::npos ||
                                     quotes_number(message, option.text)))
            by_value.push_back(option.name);
        std::string snake = option.name;
        std::replace(snake.begin(), snake.end(), '-', '_');
        if (std::find(identifiers.begin(), identifiers.end(), snake) != identifiers.end())
            (snake.find('_') != std::string::npos ? by_field : by_word).push_back(option.name);
        else
            for (const std::string& id : identifiers)
                if (id.find('_') != std::string::npos &&
                    (up_to_underscore(id, snake) || up_to_underscore(snake, id))) {
                    by_prefix.push_back(option.name);
                    break;
                }
    }
    for (const auto* found : {&by_value, &by_field, &by_word, &by_prefix})
        if (!found->empty()) return found->size() == 1 ? " (--" + found->front() + ")" : "";
    return "";
}

}  // namespace rgbd
