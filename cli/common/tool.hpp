// The driver every rgbd-<verb> tool runs through (cli/README.md): option parsing, --help,
// --version, input/output handling (files or stdin/stdout, atomic output files), messages,
// progress on a terminal only, --metrics, --threads, --seed, exit codes 0/1/2.
// Modelled on PDAL's Kernel (parse, run, catch-all, exit codes).
#pragma once

#include <atomic>
#include <boost/program_options.hpp>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <initializer_list>
#include <iosfwd>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <type_traits>
#include <vector>

#include "io/ply_stream.hpp"
#include "toolkit/error.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"

namespace rgbd::io {
class OutputFile;
}

namespace rgbd::cli {

namespace po = boost::program_options;

inline constexpr const char* kVersion = "0.1.0";

/// Thrown for usage errors (exit code 2).
class UsageError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

/// rgbd::option_named_by (toolkit/option_names.hpp) over the options given with a value in `vm`
/// (not defaulted, not flags): the option a usage error is about, as " (--name)", or "".
std::string option_named_by(const std::string& message, const po::variables_map& vm);

/// The values a numeric option allows, checked by run_tool for a value given on the command
/// line: {"voxel-mm", Range::closed(0, 1000), "mm"} -> "--voxel-mm must be in [0, 1000] mm,
/// got 1e300". For the options whose library check leaves a side open (no upper end, a mode
/// whose options struct is not checked when another mode runs).
struct OptionRange {
    std::string option;  ///< without dashes
    Range range;
    std::string unit = {};  ///< for the message ("mm", "degrees"); may be empty
};

/// Options that apply only in some modes: {{"density"}, {"beta", "reference"}}. Giving one of
/// `options` without any of `modes` (flags or options, given on the command line) is a usage
/// error "--beta applies only with --density", not a value the run ignores. With `not_with`,
/// the options apply in every mode but these (the tool's default mode among them):
/// {{"density"}, {"c-min"}, true} -> "--c-min does not apply with --density".
struct OptionScope {
    std::vector<std::string> modes;    ///< without dashes
    std::vector<std::string> options;  ///< without dashes
    bool not_with = false;
};

/// What a tool declares about itself: a tool declares it in its file's anonymous namespace with
/// designated initializers (`const ToolSpec kSpec{.name = ..., .usage = ..., ...}`), in the
/// order of the fields, next to its body `void run_<verb>(Context&)`; its main() is
/// `return cli::run_tool(argc, argv, kSpec, run_<verb>);`.
struct ToolSpec {
    std::string name;           ///< "rgbd-clean"
    std::string usage;          ///< "rgbd-clean [options] [FILE...]"
    std::string description;    ///< one paragraph
    std::string example;        ///< an example pipeline
    bool writes_stream = true;  ///< writes a binary PLY stream / mesh to stdout by default
    bool reads_stream = true;   ///< positional inputs are PLY streams (none or - = stdin)
    /// Positional .pcd, .xyz and .pwn files are read with io::read_point_cloud as one
    /// unorganised view each (no grid, no pose, view id = input position) instead of as streams.
    bool reads_cloud_files = false;
    bool whole_stream =
        false;  ///< reads the whole stream before writing ("reads the whole stream")
    /// -o names a file the tool writes itself (a mesh, a picture, JSON): like a stream tool's,
    /// its folder must exist before the work starts. (Not for a folder the tool creates.)
    bool writes_file = false;
    /// Ranges of options (checked before the tool's body runs). Every option is also checked
    /// without a declaration here: a floating-point value must be finite, an unsigned one
    /// must not be written negative (Boost would wrap -1 to 2^64 - 1).
    std::vector<OptionRange> ranges = {};
    std::vector<OptionScope> scopes = {};  ///< options of modes (checked before the body runs)
    std::function<void(po::options_description&)> add_options;  ///< tool-specific options
};

/// The checks of ToolSpec::ranges and ToolSpec::scopes and the ones every option gets, over the
/// options of `parsed` stored in `vm`. Throws UsageError naming the option. (run_tool calls it.)
void check_option_values(const ToolSpec& spec, const po::parsed_options& parsed,
                         const po::variables_map& vm);

/// An option value with the placeholder --help shows for it: `value<int>("N")`.
template <typename T>
po::typed_value<T>* value(const char* placeholder) {
    return po::value<T>()->value_name(placeholder);
}
/// An option value with a default and a placeholder: `value<double>(2.0, "X")`. Where the option
/// sets a field of a library options struct, take the default from the struct,
/// `value(denoise::DistanceOptions{}.c_min, "N")`: --help then shows the library's default, and
/// the pipe of single tools and rgbd-reconstruct (which calls the library) cannot drift apart.
/// --help writes a floating-point default as its shortest text ("0.6", not boost's
/// "0.59999999999999998").
template <typename T>
po::typed_value<T>* value(const T& fallback, const char* placeholder) {
    po::typed_value<T>* v = po::value<T>()->value_name(placeholder);
    if constexpr (std::is_floating_point_v<T>)
        return v->default_value(fallback, format_number(static_cast<double>(fallback)));
    else
        return v->default_value(fallback);
}

class Context;
using ToolMain = std::function<void(Context&)>;

/// Runs a tool: parses argv, handles the common options, calls `body`, maps errors to exit
/// codes. Returns the exit code for main().
int run_tool(int argc, char** argv, const ToolSpec& spec, const ToolMain& body);

/// Progress of one stage on stderr. On a terminal: a bar that never goes backwards. Elsewhere
/// (a log file, a batch job): plain lines from a background thread, so a stage whose algorithm
/// reports rarely still shows it is alive: "started" once the stage has run a second (quick
/// stages and runs that fail early print none), then percent and elapsed time every
/// `heartbeat_s` (10 s by default) while it runs, and "done in N s" when it ends ("stopped
/// after N s" when an exception ends it). Percentages never go backwards in either mode.
/// Off with -q.
class ProgressBar {
public:
    enum class Mode { kOff, kTerminal, kLog };
    ProgressBar(std::string label, Mode mode, double heartbeat_s = 10.0);
    ~ProgressBar();
    ProgressBar(const ProgressBar&) = delete;
    ProgressBar& operator=(const ProgressBar&) = delete;
    /// Updates the bar with the fraction done; always returns true (no cancel). Thread-safe.
    bool update(double fraction);
    /// A Progress callback bound to this bar.
    Progress callback();

private:
    double elapsed_s() const;
    void heartbeat();
    std::string label_;
    Mode mode_;
    double heartbeat_s_;
    std::atomic<int> percent_{-1};  ///< highest percentage reported so far (-1: none)
    int shown_percent_ = -1;        ///< terminal: the percentage on screen
    std::mutex mutex_;              ///< guards shown_percent_, stop_ and stderr writes
    std::condition_variable wake_;
    bool stop_ = false;
    bool started_ = false;  ///< log mode: the "started" line was printed
    int unwinding_;         ///< std::uncaught_exceptions() at construction
    std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
    std::thread beat_;  ///< log mode: the heartbeat thread
};

/// State of one tool run, handed to the tool's body.
class Context {
public:
    /// `verbosity`: how often -v was given (--quiet overrides it with -1).
    Context(const ToolSpec& spec, po::variables_map vm, std::vector<std::string> inputs,
            std::vector<std::string> args, int verbosity);
    ~Context();

    const ToolSpec& spec() const { return spec_; }
    const po::variables_map& options() const { return vm_; }
    template <typename T>
    T get(const std::string& name) const {
        return vm_[name].as<T>();
    }
    bool has(const std::string& name) const {
        return vm_.count(name) > 0 && !vm_[name].defaulted();
    }
    const std::vector<std::string>& inputs() const { return inputs_; }
    int verbosity() const { return verbosity_; }
    std::uint64_t seed() const { return seed_; }

    /// Messages on stderr: "rgbd-<verb>: warning: ...". info() only with -v.
    void warn(const std::string& message) const;
    void info(const std::string& message) const;
    void note(const std::string& message) const;  ///< shown unless -q
    ProgressBar progress(const std::string& label) const;

    // ---- input ----
    /// Calls `handler` for every document of every input (files or stdin), in order; with
    /// ToolSpec::reads_cloud_files, a .pcd/.xyz/.pwn input is one point document.
    void for_each_document(const std::function<void(io::Document&)>& handler);
    /// for_each_document for a tool that works on point views: calls `handler` with the view of
    /// every point document and then writes the document; mesh documents are passed through.
    void for_each_view(const std::function<void(PointCloud&)>& handler);
    /// Writes a mesh document unchanged with the warning "document N is a mesh; passed through".
    void pass_through(io::Document& mesh);
    /// Reads every document of every input. Throws InputError for an empty stream.
    std::vector<io::Document> read_all_documents();

    // ---- output ----
    /// The output stream (-o FILE written atomically at commit(), or stdout). Refuses to
    /// write binary to a terminal (UsageError).
    std::ostream& out();
    /// Path given with -o, or empty for stdout.
    std::string output_path() const;
    /// Writes a document with this tool's history line appended.
    void write(io::Document& document);
    /// Appends "rgbd-<verb> <version> <args>" to the view's history.
    void add_history(ViewInfo& view) const;

    // ---- metrics ----
    Report& metrics() { return metrics_; }
    /// Appends one per-document result to metrics["documents"].
    void add_document_metrics(Report result);

    /// Called by run_tool before the body: fails at once, not after the work, when a stream
    /// tool's output would go to a terminal (UsageError) or when -o of a stream tool or of a
    /// `writes_file` tool, or --metrics FILE, names a folder that does not exist (IoError).
    void check_output() const;
    /// Called by run_tool after the body returned: renames the output and metrics files.
    void commit();

private:
    const ToolSpec& spec_;
    po::variables_map vm_;
    std::vector<std::string> inputs_;
    std::vector<std::string> args_;
    int verbosity_ = 0;
    std::uint64_t seed_ = 0;
    Report metrics_;
    std::unique_ptr<io::OutputFile> file_out_;
    std::string output_path_;
    std::size_t documents_written_ = 0;
};

/// Parses "a:b[:step]" or a single integer into a list of non-negative integers (bounded by
/// `count` for open ranges "a:"). Throws UsageError.
std::vector<long long> parse_range(const std::string& text, long long count);
/// Parses a comma-separated list of doubles. Throws UsageError naming the option.
std::vector<double> parse_doubles(const std::string& text, const std::string& option);
/// `text` with each "{}" replaced by the next of `values` as format_number writes them: the
/// help of an option whose default depends on the mode, read from the options structs, e.g.
/// with_numbers("default {} for --distance, {} for --density", {16, 20}). Pass `.c_str()` to
/// add_options() (boost copies the text).
std::string with_numbers(std::string_view text, std::initializer_list<double> values);
/// printf's formatting into a string, for the numbers of message lines ("%.3f", "%.1f mm").
[[gnu::format(printf, 1, 2)]] std::string formatted(const char* format, ...);

}  // namespace rgbd::cli
