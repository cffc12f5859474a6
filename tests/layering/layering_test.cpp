// Enforces the dependency rules of STYLE.md §2 on the source tree: which top-level folder may
// include which, algorithms/internal stays inside algorithms/, and public algorithm headers
// include no CGAL headers.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <string>

namespace fs = std::filesystem;

namespace {

const std::map<std::string, std::set<std::string>> kAllowed = {
    {"toolkit", {"toolkit"}},
    {"io", {"toolkit", "io"}},
    {"algorithms", {"toolkit", "algorithms"}},
    {"sensors", {"toolkit", "io", "sensors"}},
    {"pipeline", {"toolkit", "io", "algorithms", "pipeline"}},
    {"cli", {"toolkit", "io", "algorithms", "sensors", "pipeline", "cli"}},
    {"validation", {"toolkit", "io", "algorithms", "validation"}},
};

/// Narrower exceptions: a subfolder that may also depend on a folder its top may not. The fuzz
/// targets feed bytes to the capture network's message parsers (sensors/network/protocol).
const std::map<std::string, std::set<std::string>> kAllowedBelow = {
    {"validation/robustness/fuzz", {"sensors"}},
};

bool allowed_below(const fs::path& relative_file, const std::string& top) {
    for (const auto& [prefix, extra] : kAllowedBelow)
        if (relative_file.generic_string().rfind(prefix + "/", 0) == 0 && extra.count(top))
            return true;
    return false;
}

struct Include {
    fs::path file;
    std::string target;
    bool angled;
};

std::vector<Include> includes_of(const fs::path& file) {
    static const std::regex kInclude(R"(^\s*#\s*include\s*([<"])([^>"]+)[>"])");
    std::vector<Include> out;
    std::ifstream in(file);
    std::string line;
    std::smatch m;
    while (std::getline(in, line))
        if (std::regex_search(line, m, kInclude)) out.push_back({file, m[2], m[1] == "<"});
    return out;
}

std::vector<fs::path> sources_under(const fs::path& dir) {
    std::vector<fs::path> files;
    if (!fs::exists(dir)) return files;
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
        const auto ext = e.path().extension();
        if (e.is_regular_file() && (ext == ".hpp" || ext == ".cpp" || ext == ".h"))
            files.push_back(e.path());
    }
    return files;
}

}  // namespace

TEST(Layering, FoldersIncludeOnlyWhatStyleAllows) {
    const fs::path root = RGBD_SOURCE_DIR;
    std::size_t checked = 0;
    for (const auto& [folder, allowed] : kAllowed) {
        for (const auto& file : sources_under(root / folder)) {
            for (const auto& inc : includes_of(file)) {
                if (inc.angled) continue;
                const std::string top = inc.target.substr(0, inc.target.find('/'));
                if (!kAllowed.count(top)) continue;  // a local include such as "foo.hpp"
                ++checked;
                EXPECT_TRUE(allowed.count(top) || allowed_below(fs::relative(file, root), top))
                    << fs::relative(file, root) << " includes " << inc.target << " but " << folder
                    << "/ may not depend on " << top << "/";
                if (inc.target.rfind("algorithms/internal/", 0) == 0) {
                    EXPECT_EQ(folder, "algorithms")
                        << fs::relative(file, root) << " includes " << inc.target
                        << ": algorithms/internal is private to algorithms/";
                }
            }
        }
    }
    EXPECT_GT(checked, 10u) << "no includes found: is RGBD_SOURCE_DIR right?";
}

TEST(Layering, PublicAlgorithmHeadersIncludeNoCgal) {
    const fs::path root = RGBD_SOURCE_DIR;
    for (const auto& file : sources_under(root / "algorithms")) {
        if (file.extension() != ".hpp") continue;
        if (file.string().find("/internal/") != std::string::npos) continue;
        for (const auto& inc : includes_of(file)) {
            EXPECT_FALSE(inc.angled && inc.target.rfind("CGAL/", 0) == 0)
                << fs::relative(file, root) << " includes <" << inc.target
                << ">: CGAL algorithm headers belong in .cpp files (STYLE.md §2)";
        }
    }
}
