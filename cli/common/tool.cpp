#include "cli/common/tool.hpp"

#include <malloc.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <mutex>
#include <sstream>

#include "io/capture_folder.hpp"
#include "io/mesh_io.hpp"
#include "io/output_file.hpp"
#include "toolkit/error.hpp"
#include "toolkit/option_names.hpp"

namespace rgbd::cli {

namespace fs = std::filesystem;

namespace {

/// Writes `text` (whole lines) to stderr in one piece: straight into std::cerr's buffer under
/// one lock, so messages from the tool's threads (a capture hub's control and live-stream
/// threads, a progress heartbeat) neither interleave nor race on the buffer. run_tool unties
/// std::cerr from std::cout, so nothing here flushes stdout while another thread writes it.
void write_stderr(const std::string& text) {
    static std::mutex mutex;
    std::lock_guard lock(mutex);
    std::cerr.rdbuf()->sputn(text.data(), static_cast<std::streamsize>(text.size()));
    std::cerr.rdbuf()->pubsync();
}

}  // namespace

// ---------------------------------------------------------------- ProgressBar

ProgressBar::ProgressBar(std::string label, Mode mode, double heartbeat_s)
    : label_(std::move(label)),
      mode_(mode),
      heartbeat_s_(heartbeat_s),
      unwinding_(std::uncaught_exceptions()) {
    if (mode_ == Mode::kLog) beat_ = std::thread([this] { heartbeat(); });
}

ProgressBar::~ProgressBar() {
    if (mode_ == Mode::kTerminal && shown_percent_ >= 0) write_stderr("\r\033[K");
    if (mode_ != Mode::kLog) return;
    {
        std::lock_guard lock(mutex_);
        stop_ = true;
    }
    wake_.notify_all();
    beat_.join();
    if (!started_) return;  // a quick stage, or a run that failed early: no lines
    char line[64];
    if (std::uncaught_exceptions() > unwinding_)
        std::snprintf(line, sizeof line, ": stopped after %.1f s\n", elapsed_s());
    else
        std::snprintf(line, sizeof line, ": done in %.1f s\n", elapsed_s());
    write_stderr(label_ + line);
}

double ProgressBar::elapsed_s() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void ProgressBar::heartbeat() {
    using Clock = std::chrono::steady_clock;
    const auto after = [](double s) {
        return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
    };
    std::unique_lock lock(mutex_);
    // The first line after a second (quick stages print none), then one every heartbeat_s_.
    auto next = start_ + after(1.0);
    while (!wake_.wait_until(lock, next, [this] { return stop_; })) {
        const int percent = std::max(0, percent_.load());
        char line[96];
        std::snprintf(line, sizeof line,
                      started_ ? ": %d%% after %.1f s\n" : ": started, %d%% after %.1f s\n",
                      percent, elapsed_s());
        // Never `std::cerr <<` from this thread: were std::cerr still tied to std::cout, its
        // sentry would flush std::cout while the tool's thread writes its stream to it (a data
        // race that corrupted rgbd-cloud's PLY stream in a pipe). write_stderr takes neither.
        write_stderr(label_ + line);
        started_ = true;
        next += after(heartbeat_s_);
    }
}

bool ProgressBar::update(double fraction) {
    if (mode_ == Mode::kOff) return true;
    // Never backwards: a stage whose parts report their own fractions may restart at 0.
    const int percent = static_cast<int>(std::lround(std::clamp(fraction, 0.0, 1.0) * 100.0));
    int seen = percent_.load();
    while (percent > seen && !percent_.compare_exchange_weak(seen, percent)) {
    }
    if (mode_ == Mode::kLog) return true;  // the heartbeat thread prints
    std::lock_guard lock(mutex_);
    const int shown = percent_.load();
    if (shown == shown_percent_) return true;
    shown_percent_ = shown;
    const int width = 30, filled = shown * width / 100;
    write_stderr("\r" + label_ + " [" + std::string(filled, '=') +
                 std::string(width - filled, ' ') + "] " + std::to_string(shown) + "%");
    return true;
}

Progress ProgressBar::callback() {
    return [this](double fraction) { return update(fraction); };
}

// ---------------------------------------------------------------- Context

Context::Context(const ToolSpec& spec, po::variables_map vm, std::vector<std::string> inputs,
                 std::vector<std::string> args, int verbosity)
    : spec_(spec), vm_(std::move(vm)), inputs_(std::move(inputs)), args_(std::move(args)) {
    verbosity_ = vm_.count("quiet") ? -1 : verbosity;
    seed_ = vm_["seed"].as<std::uint64_t>();
    if (vm_.count("output")) {
        const std::string out = vm_["output"].as<std::string>();
        if (out != "-") output_path_ = out;
    }
    std::string joined;
    for (const auto& a : args_) joined += (joined.empty() ? "" : " ") + a;
    metrics_ = Report::object();
    metrics_["tool"] = spec_.name;
    metrics_["version"] = kVersion;
    metrics_["args"] = args_;
    metrics_["inputs"] = inputs_;
    metrics_["documents"] = Report::array();
}

Context::~Context() = default;  // an uncommitted output file removes its temporary

void Context::warn(const std::string& message) const {
    if (verbosity_ >= -1) write_stderr(spec_.name + ": warning: " + message + "\n");
}
void Context::info(const std::string& message) const {
    if (verbosity_ >= 1) write_stderr(spec_.name + ": " + message + "\n");
}
void Context::note(const std::string& message) const {
    if (verbosity_ >= 0) write_stderr(spec_.name + ": " + message + "\n");
}

ProgressBar Context::progress(const std::string& label) const {
    using Mode = ProgressBar::Mode;
    const Mode mode = verbosity_ < 0               ? Mode::kOff
                      : isatty(STDERR_FILENO) != 0 ? Mode::kTerminal
                                                   : Mode::kLog;
    return ProgressBar(spec_.name + ": " + label, mode);
}

namespace {

/// A plain point-cloud file that is not a PLY stream (read with io::read_point_cloud).
bool is_cloud_file(const std::string& input) {
    std::string ext = fs::path(input).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return ext == ".pcd" || ext == ".xyz" || ext == ".pwn";
}

}  // namespace

void Context::for_each_document(const std::function<void(io::Document&)>& handler) {
    std::vector<std::string> inputs = inputs_;
    if (inputs.empty()) inputs.push_back("-");
    std::size_t total = 0;
    for (const std::string& input : inputs) {
        std::unique_ptr<std::ifstream> file;
        std::istream* in = &std::cin;
        std::string name = "<stdin>";
        if (input != "-" && spec_.reads_cloud_files && is_cloud_file(input)) {
            RGBD_CHECK_AS(IoError, fs::exists(input), input + ": no such file");
            io::Document document;
            document.kind = io::DocumentKind::kPoints;
            document.cloud = io::read_point_cloud(input);
            if (document.cloud.view.id < 0) document.cloud.view.id = static_cast<int>(total);
            if (document.cloud.view.source.empty()) document.cloud.view.source = input;
            ++total;
            handler(document);
            continue;
        }
        if (input != "-") {
            RGBD_CHECK_AS(IoError, fs::exists(input), input + ": no such file");
            file = std::make_unique<std::ifstream>(input, std::ios::binary);
            RGBD_CHECK_AS(IoError, file->good(), input + ": cannot open for reading");
            in = file.get();
            name = input;
        } else if (isatty(STDIN_FILENO)) {
            throw UsageError("no input: give a file or pipe a PLY stream into stdin");
        }
        io::PlyStreamReader reader(*in, name);
        io::Document document;
        while (reader.next(document)) {
            ++total;
            handler(document);
            document = io::Document{};
        }
        if (reader.count() == 0) throw InputError(name + ": empty input stream (no PLY document)");
    }
    if (total == 0) throw InputError("empty input stream (no PLY document)");
}

void Context::for_each_view(const std::function<void(PointCloud&)>& handler) {
    for_each_document([&](io::Document& document) {
        if (document.kind != io::DocumentKind::kPoints) return pass_through(document);
        handler(document.cloud);
        write(document);
    });
}

void Context::pass_through(io::Document& mesh) {
    warn("document " + std::to_string(mesh.cloud.view.id) + " is a mesh; passed through");
    write(mesh);
}

std::vector<io::Document> Context::read_all_documents() {
    std::vector<io::Document> documents;
    for_each_document([&](io::Document& d) { documents.push_back(std::move(d)); });
    return documents;
}

void Context::check_output() const {
    if (vm_.count("metrics") && vm_["metrics"].as<std::string>() != "-")
        io::check_output_path(vm_["metrics"].as<std::string>());
    if (!output_path_.empty()) {
        if (spec_.writes_stream || spec_.writes_file) io::check_output_path(output_path_);
    } else if (spec_.writes_stream && isatty(STDOUT_FILENO)) {
        throw UsageError("refusing to write binary data to a terminal: use -o FILE or a pipe");
    }
}

std::ostream& Context::out() {
    if (!output_path_.empty()) {
        // A regular file is written to a temporary renamed at commit(); /dev/null or a FIFO in
        // place (io/output_file.hpp).
        if (!file_out_) file_out_ = std::make_unique<io::OutputFile>(output_path_);
        return file_out_->stream();
    }
    return std::cout;
}

std::string Context::output_path() const { return output_path_; }

void Context::add_history(ViewInfo& view) const {
    std::string line = spec_.name + " " + kVersion;
    for (const auto& a : args_) line += " " + a;
    view.history.push_back(line);
}

void Context::write(io::Document& document) {
    add_history(document.cloud.view);
    io::write_document(out(), document);
    ++documents_written_;
}

void Context::add_document_metrics(Report result) {
    metrics_["documents"].push_back(std::move(result));
}

void Context::commit() {
    // The metrics file is in place before the output is renamed into place: when it cannot be
    // written, the run fails with neither (the destructor removes the output's temporary).
    if (file_out_) {
        RGBD_CHECK_AS(IoError, file_out_->close(), output_path_ + ": write failed (disk full?)");
    } else if (output_path_.empty()) {
        std::cout.flush();
        RGBD_CHECK_AS(IoError, std::cout.good(), "<stdout>: write failed");
    }
    if (vm_.count("metrics")) {
        const std::string path = vm_["metrics"].as<std::string>();
        metrics_["status"] = "ok";
        const std::string text = metrics_.dump(2) + "\n";
        if (path == "-")
            std::cout << text << std::flush;
        else
            io::write_text_atomic(path, text);  // in place for /dev/null or a FIFO
    }
    if (file_out_) file_out_->commit();
}

// ---------------------------------------------------------------- helpers

std::vector<long long> parse_range(const std::string& text, long long count) {
    std::vector<long long> parts;
    std::stringstream ss(text);
    std::string item;
    std::vector<std::string> fields;
    while (std::getline(ss, item, ':')) fields.push_back(item);
    if (text.empty() || fields.empty() || fields.size() > 3 ||
        (text.back() == ':' && fields.size() == 3))
        throw UsageError("bad range '" + text + "' (expected N or A:B[:STEP])");
    auto number = [&](const std::string& s, long long fallback) -> long long {
        if (s.empty()) return fallback;
        std::size_t used = 0;
        long long v = 0;
        try {
            v = std::stoll(s, &used);
        } catch (...) {
            used = 0;
        }
        if (used != s.size() || v < 0)
            throw UsageError("bad range '" + text + "' (numbers must be non-negative integers)");
        return v;
    };
    if (fields.size() == 1) {
        if (text.find(':') == std::string::npos) return {number(fields[0], 0)};
    }
    const long long a = number(fields[0], 0);
    const long long b = fields.size() >= 2 ? number(fields[1], count) : count;
    const long long step = fields.size() == 3 ? number(fields[2], 1) : 1;
    if (step <= 0) throw UsageError("bad range '" + text + "' (step must be positive)");
    std::vector<long long> out;
    for (long long i = a; i < b; i += step) out.push_back(i);
    return out;
}

std::vector<double> parse_doubles(const std::string& text, const std::string& option) {
    std::vector<double> values;
    std::stringstream ss(text);
    std::string item;
    while (std::getline(ss, item, ',')) {
        std::size_t used = 0;
        double v = 0;
        try {
            v = std::stod(item, &used);
        } catch (...) {
            used = 0;
        }
        if (used != item.size() || !std::isfinite(v))
            throw UsageError("--" + option + ": '" + item + "' is not a number");
        values.push_back(v);
    }
    if (values.empty()) throw UsageError("--" + option + ": expected a comma-separated list");
    return values;
}

std::string with_numbers(std::string_view text, std::initializer_list<double> values) {
    std::string out;
    auto value = values.begin();
    for (std::size_t at = 0; at < text.size();) {
        const std::size_t hole = text.find("{}", at);
        out.append(text.substr(at, hole == std::string_view::npos ? text.npos : hole - at));
        if (hole == std::string_view::npos) break;
        RGBD_CHECK(value != values.end(),
                   "with_numbers: more {} than values in: " + std::string(text));
        out += format_number(*value++);
        at = hole + 2;
    }
    RGBD_CHECK(value == values.end(), "with_numbers: more values than {} in: " + std::string(text));
    return out;
}

std::string formatted(const char* format, ...) {
    std::va_list args;
    va_start(args, format);
    std::va_list again;
    va_copy(again, args);
    const int size = std::vsnprintf(nullptr, 0, format, args);
    va_end(args);
    std::string text(size > 0 ? std::size_t(size) : 0, '\0');
    if (size > 0) std::vsnprintf(text.data(), text.size() + 1, format, again);
    va_end(again);
    return text;
}

// ---------------------------------------------------------------- run_tool

namespace {
/// A numeric option value as check_range's messages write it ("got 1e300", "got -1").
std::optional<std::string> number_text(const boost::any& value) {
    if (const auto* d = boost::any_cast<double>(&value)) return format_number(*d);
    if (const auto* i = boost::any_cast<int>(&value)) return std::to_string(*i);
    if (const auto* l = boost::any_cast<long long>(&value)) return std::to_string(*l);
    if (const auto* l = boost::any_cast<long>(&value)) return std::to_string(*l);
    if (const auto* u = boost::any_cast<unsigned long>(&value)) return std::to_string(*u);
    return std::nullopt;
}

/// A numeric option value as a double (integers exactly up to 2^53), or none.
std::optional<double> number_of(const boost::any& value) {
    if (const auto* d = boost::any_cast<double>(&value)) return *d;
    if (const auto* f = boost::any_cast<float>(&value)) return *f;
    if (const auto* i = boost::any_cast<int>(&value)) return *i;
    if (const auto* l = boost::any_cast<long long>(&value)) return double(*l);
    if (const auto* l = boost::any_cast<long>(&value)) return double(*l);
    if (const auto* u = boost::any_cast<unsigned long>(&value)) return double(*u);
    if (const auto* u = boost::any_cast<unsigned>(&value)) return *u;
    return std::nullopt;
}

bool is_unsigned(const boost::any& value) {
    return value.type() == typeid(unsigned long) || value.type() == typeid(unsigned) ||
           value.type() == typeid(unsigned long long) || value.type() == typeid(unsigned short);
}

/// "--a", "--a or --b", "--a, --b or --c".
std::string option_list(const std::vector<std::string>& names) {
    std::string text;
    for (std::size_t i = 0; i < names.size(); ++i) {
        if (i > 0) text += i + 1 == names.size() ? " or " : ", ";
        text += "--" + names[i];
    }
    return text;
}

bool given(const po::variables_map& vm, const std::string& name) {
    return vm.count(name) > 0 && !vm[name].defaulted();
}
}  // namespace

void check_option_values(const ToolSpec& spec, const po::parsed_options& parsed,
                         const po::variables_map& vm) {
    // Every option: the text as typed, checked against the type it was stored as.
    for (const po::option& o : parsed.options) {
        if (o.string_key.empty() || o.string_key == "input" || !vm.count(o.string_key)) continue;
        const boost::any& value = vm[o.string_key].value();
        for (const std::string& token : o.value)
            if (is_unsigned(value) && token.find('-') != std::string::npos)
                throw UsageError("--" + o.string_key + " must be >= 0, got " + token);
        if (const auto v = number_of(value); v && !std::isfinite(*v))
            throw UsageError("--" + o.string_key + " must be a finite number, got " +
                             (o.value.empty() ? format_number(*v) : o.value.back()));
    }
    for (const OptionScope& scope : spec.scopes) {
        const auto mode = std::find_if(scope.modes.begin(), scope.modes.end(),
                                       [&](const std::string& m) { return given(vm, m); });
        if ((mode != scope.modes.end()) != scope.not_with) continue;
        for (const std::string& name : scope.options)
            if (given(vm, name))
                throw UsageError("--" + name +
                                 (scope.not_with
                                      ? " does not apply with --" + *mode
                                      : " applies only with " + option_list(scope.modes)));
    }
    for (const OptionRange& r : spec.ranges) {
        if (!given(vm, r.option)) continue;
        const auto v = number_of(vm[r.option].value());
        if (!v) throw std::logic_error(spec.name + ": range of non-numeric option --" + r.option);
        if (!r.range.contains(*v))
            throw UsageError("--" + r.option + " must be in " + r.range.to_string() +
                             (r.unit.empty() ? "" : " " + r.unit) + ", got " +
                             number_text(vm[r.option].value()).value_or(format_number(*v)));
    }
}

std::string option_named_by(const std::string& message, const po::variables_map& vm) {
    std::vector<GivenOption> given;
    for (const auto& [name, value] : vm) {
        // Given options with a value; not flags (--statistical names a mode, not a value).
        if (value.defaulted() || name == "input" || value.value().empty() ||
            value.value().type() == typeid(bool) ||
            value.value().type() == typeid(std::vector<bool>))
            continue;
        if (const auto* text = boost::any_cast<std::string>(&value.value()))
            given.push_back({name, *text});
        else
            given.push_back({name, number_text(value.value()).value_or("")});
    }
    return rgbd::option_named_by(message, given);
}

namespace {

std::string help_text(const ToolSpec& spec, const po::options_description& visible) {
    std::ostringstream h;
    h << "Usage: " << spec.usage << "\n\n" << spec.description << "\n";
    if (spec.whole_stream) h << "\nThis tool reads the whole stream before it writes.\n";
    h << "\n" << visible << "\nExample:\n  " << spec.example << "\n";
    h << "\nExit codes: 0 ok, 1 runtime failure (bad input, I/O, algorithm), 2 usage error.\n";
    return h.str();
}

/// glibc's allocator serves every block over its mmap threshold (128 KiB, rising to at most
/// 32 MiB as blocks are freed) with a fresh mmap and gives it back to the kernel on free, and
/// trims the heap top past 128 KiB: a stage that builds and drops a view-sized buffer per view
/// (kd-trees, grids, copies of clouds) pays a page fault and a zeroed page for every 4 KiB of
/// it, again for every view. Keep freed memory for reuse up to 1 GiB: a batch tool runs for
/// seconds to minutes; a long-running one (a node, the hub, the viewer) keeps a resident size
/// near its own peak instead of returning what it freed. Person job (50 views, 2 cores): 614-689 k
/// -> 330-332 k minor faults, system time 5.7-7.6 -> 3.6-4.0 s (docs/algorithms.md, speed).
void keep_freed_memory() {
    constexpr int kKeep = 1 << 30;
    mallopt(M_MMAP_THRESHOLD, kKeep);
    mallopt(M_TRIM_THRESHOLD, kKeep);
}

}  // namespace

int run_tool(int argc, char** argv, const ToolSpec& spec, const ToolMain& body) {
    keep_freed_memory();
    std::ios::sync_with_stdio(false);
    // std::cerr is tied to std::cout by default: every `std::cerr <<` would first flush
    // std::cout, from whichever thread writes the message, while the tool's own thread may be
    // writing its data stream to std::cout (a data race that corrupts the stream). Errors and
    // progress go out unbuffered anyway (std::cerr is unitbuf); stdout is flushed at exit.
    std::cerr.tie(nullptr);
    po::options_description tool_options("Options");
    if (spec.add_options) spec.add_options(tool_options);
    po::options_description common("Common options");
    common.add_options()("help,h", "print this help and exit")("version",
                                                               "print the version and exit")(
        "output,o", po::value<std::string>()->value_name("FILE"),
        spec.writes_stream ? "output file (default: stdout; - = stdout)" : "output file")(
        "metrics", po::value<std::string>()->value_name("FILE"),
        "write a JSON object with the run's results (- = stdout, only with -o FILE)")(
        "threads", po::value<int>()->default_value(0)->value_name("N"),
        "worker threads (0 = all cores)")(
        "seed", po::value<std::uint64_t>()->default_value(0)->value_name("N"), "random seed")(
        "verbose,v", po::value<std::vector<bool>>()->zero_tokens()->composing(),
        "more messages (repeatable)")("quiet,q", "only errors")(
        "debug", "let exceptions escape (for a debugger)");
    po::options_description hidden;
    hidden.add_options()("input", po::value<std::vector<std::string>>(), "inputs");
    po::options_description all;
    all.add(tool_options).add(common).add(hidden);
    po::options_description visible;
    visible.add(tool_options).add(common);
    po::positional_options_description positional;
    positional.add("input", -1);

    std::vector<std::string> args(argv + 1, argv + argc);
    bool debug = false;
    for (const auto& a : args)
        if (a == "--debug") debug = true;

    auto fail = [&](int code, const std::string& message) {
        write_stderr(spec.name + ": error: " + message + "\n" +
                     (code == 2 ? "Try '" + spec.name + " --help' for more information.\n" : ""));
        return code;
    };

    po::variables_map vm;
    int verbosity = 0;
    try {
        const po::parsed_options parsed =
            po::command_line_parser(argc, argv).options(all).positional(positional).run();
        po::store(parsed, vm);
        // Each -v is one occurrence; the stored vector of a zero-token option stays empty.
        for (const po::option& o : parsed.options)
            if (o.string_key == "verbose") ++verbosity;
        if (vm.count("help")) {
            std::cout << help_text(spec, visible);
            return 0;
        }
        if (vm.count("version")) {
            std::cout << spec.name << " " << kVersion << "\n";
            return 0;
        }
        po::notify(vm);
        if (vm.count("metrics") && vm["metrics"].as<std::string>() == "-" &&
            (!vm.count("output") || vm["output"].as<std::string>() == "-") && spec.writes_stream)
            throw UsageError("--metrics - needs -o FILE (stdout carries the data)");
        if (vm["threads"].as<int>() < 0 || vm["threads"].as<int>() > 1024)
            throw UsageError("--threads must be between 0 and 1024");
        check_option_values(spec, parsed, vm);
    } catch (const po::error& e) {
        return fail(2, e.what());
    } catch (const UsageError& e) {
        return fail(2, e.what());
    }

    std::vector<std::string> inputs;
    if (vm.count("input")) inputs = vm["input"].as<std::vector<std::string>>();
    std::unique_ptr<tbb::global_control> threads;
    if (vm["threads"].as<int>() > 0)
        threads = std::make_unique<tbb::global_control>(
            tbb::global_control::max_allowed_parallelism,
            static_cast<std::size_t>(vm["threads"].as<int>()));

    try {
        Context context(spec, vm, inputs, args, verbosity);
        context.check_output();
        body(context);
        context.commit();
        return 0;
    } catch (const UsageError& e) {
        if (debug) throw;
        return fail(2, e.what() + option_named_by(e.what(), vm));
    } catch (const po::error& e) {
        if (debug) throw;
        return fail(2, e.what());
    } catch (const rgbd::Error& e) {
        if (debug) throw;
        return fail(1, e.what());
    } catch (const std::exception& e) {
        if (debug) throw;
        return fail(1, std::string("internal error: ") + e.what());
    }
}

}  // namespace rgbd::cli
