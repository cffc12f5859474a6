// Enforces the dependency rules of docs/architecture.md on the source tree: which top-level
// folder may include which, algorithms/internal stays inside algorithms/, and CGAL stays behind
// the data model: only toolkit/types.hpp, point_cloud.hpp and mesh.hpp include CGAL headers (the
// kernel, Point_set_3, Surface_mesh) and name CGAL types; every other public header of the
// libraries uses their aliases (Point_3, PointSet, Mesh) and includes no CGAL header. And an
// installed header includes only installed ones (the install rule of CMakeLists.txt).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
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

/// The headers that define the data model on CGAL's types, and the CGAL headers they may use.
const std::map<std::string, std::set<std::string>> kDataModelHeaders = {
    {"toolkit/types.hpp", {"CGAL/Exact_predicates_inexact_constructions_kernel.h"}},
    {"toolkit/point_cloud.hpp", {"CGAL/Point_set_3.h"}},
    {"toolkit/mesh.hpp", {"CGAL/Surface_mesh.h", "CGAL/IO/Color.h"}},
};

/// The installed headers of the libraries: every .hpp of toolkit/, io/, algorithms/,
/// pipeline/ and sensors/ outside internal/ folders.
std::vector<fs::path> public_headers(const fs::path& root) {
    std::vector<fs::path> out;
    for (const char* folder : {"toolkit", "io", "algorithms", "pipeline", "sensors"})
        for (const auto& file : sources_under(root / folder))
            if (file.extension() == ".hpp" && file.string().find("/internal/") == std::string::npos)
                out.push_back(file);
    return out;
}

/// Code of a line without its // comment (good enough for headers: no "//" in strings here).
std::string code_of(const std::string& line) { return line.substr(0, line.find("//")); }

TEST(Layering, CgalOnlyInTheDataModelHeaders) {
    const fs::path root = RGBD_SOURCE_DIR;
    std::size_t checked = 0;
    for (const auto& file : public_headers(root)) {
        ++checked;
        const std::string relative = fs::relative(file, root).generic_string();
        const auto model = kDataModelHeaders.find(relative);
        for (const auto& inc : includes_of(file)) {
            if (!inc.angled || inc.target.rfind("CGAL/", 0) != 0) continue;
            EXPECT_TRUE(model != kDataModelHeaders.end() && model->second.count(inc.target))
                << relative << " includes <" << inc.target
                << ">: CGAL headers belong in .cpp files; public headers use the data model of "
                   "toolkit/ (docs/architecture.md)";
        }
        if (model != kDataModelHeaders.end()) continue;
        std::ifstream in(file);
        std::string line;
        for (int n = 1; std::getline(in, line); ++n)
            EXPECT_EQ(code_of(line).find("CGAL::"), std::string::npos)
                << relative << ":" << n << " names a CGAL type: use the toolkit's aliases";
    }
    EXPECT_GT(checked, 50u) << "no headers found: is RGBD_SOURCE_DIR right?";
}

/// The names the install rule of CMakeLists.txt leaves out (`PATTERN "x" EXCLUDE`: a file or a
/// folder of that name).
std::set<std::string> install_excludes(const fs::path& root) {
    std::ifstream in(root / "CMakeLists.txt");
    std::stringstream text;
    text << in.rdbuf();
    const std::string cmake = text.str();
    static const std::regex kPattern(R"re(PATTERN\s+"([^"]+)"\s+EXCLUDE)re");
    std::set<std::string> out;
    for (std::sregex_iterator it(cmake.begin(), cmake.end(), kPattern), end; it != end; ++it)
        out.insert((*it)[1]);
    return out;
}

bool installed(const fs::path& relative, const std::set<std::string>& excludes) {
    for (const auto& part : relative)
        if (excludes.count(part.string())) return false;
    return true;
}

// A user of the installed package (find_package(RgbdToolkit)) compiles every installed header:
// none may include a header of the libraries that the install rule leaves out.
TEST(Layering, InstalledHeadersIncludeOnlyInstalledHeaders) {
    const fs::path root = RGBD_SOURCE_DIR;
    const std::set<std::string> excludes = install_excludes(root);
    ASSERT_TRUE(excludes.count("internal")) << "the install rule of CMakeLists.txt was not found";
    const std::set<std::string> libraries = {"toolkit", "io", "algorithms", "pipeline", "sensors"};
    std::size_t checked = 0;
    for (const auto& file : public_headers(root)) {
        const fs::path relative = fs::relative(file, root);
        if (!installed(relative, excludes)) continue;
        ++checked;
        for (const auto& inc : includes_of(file)) {
            const fs::path target(inc.target);
            if (inc.angled || target.empty() || !libraries.count(target.begin()->string()))
                continue;
            EXPECT_TRUE(installed(target, excludes))
                << relative.generic_string() << " includes \"" << inc.target
                << "\", which is not installed: the installed package cannot compile it";
        }
    }
    EXPECT_GT(checked, 50u) << "no headers found: is RGBD_SOURCE_DIR right?";
}
