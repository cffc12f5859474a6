// Shared helpers of the Python module's binding files (python/bindings.cpp: the data types and
// readers; python/bindings_stages.cpp: the pipeline stages): keyword options with the tools'
// names, progress callbacks across the released GIL, views taken from Python lists, reports as
// Python dicts. No algorithm here: every stage is a call into pipeline/ or algorithms/.
#pragma once

#include <pybind11/pybind11.h>

#include <exception>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "algorithms/denoise/sensor_noise.hpp"
#include "io/capture_folder.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"

namespace rgbd::python {

namespace py = pybind11;

/// The keyword options of one call, taken one by one under the tools' option names (dashes as
/// underscores). done() raises TypeError naming the first keyword no one took.
class Options {
public:
    Options(std::string function, const py::kwargs& kwargs);

    /// Sets `field` from the keyword `name` when given (TypeError when it does not convert);
    /// returns whether it was given.
    template <typename T>
    bool get(const char* name, T& field) {
        known_.insert(name);
        if (!kwargs_.contains(name) || kwargs_[name].is_none()) return false;
        try {
            field = kwargs_[name].template cast<T>();
        } catch (const py::cast_error&) {
            throw py::type_error(
                function_ + "(): option '" + name + "' has the wrong type (" +
                std::string(py::str(py::type::of(kwargs_[name]).attr("__name__"))) + ")");
        }
        return true;
    }
    /// A flag option (the tools' --no-mask, --keep-ground...): false unless given true.
    bool flag(const char* name);
    /// The keyword's value (None when absent), marking it known.
    py::object object(const char* name);
    /// Raises TypeError "f() got an unexpected keyword argument 'x' (options: a, b, ...)".
    void done() const;

private:
    std::string function_;
    py::dict kwargs_;
    std::set<std::string> known_;
};

/// The Python progress callback progress(stage, fraction) -> bool|None (False cancels) as the
/// toolkit's Progress, callable from any thread while the GIL is released: it takes the GIL for
/// the call. A Python exception raised by the callback cancels the work and is re-raised by
/// rethrow_if_failed().
class ProgressBridge {
public:
    explicit ProgressBridge(py::object callback);
    /// The Progress of one stage; empty when there is no callback.
    Progress stage(const std::string& name);
    /// Records the Python exception being handled (call inside a catch, GIL held).
    void fail();
    /// Re-raises the recorded Python exception, if any (GIL held).
    void rethrow_if_failed() const;

private:
    py::object callback_;
    std::shared_ptr<std::exception_ptr> error_ = std::make_shared<std::exception_ptr>();
};

/// Runs `work` with the GIL released; a Python exception the progress callback raised is
/// re-raised in preference to the cancellation it caused.
template <typename F>
auto without_gil(ProgressBridge& bridge, F&& work) {
    using Result = decltype(work());
    try {
        if constexpr (std::is_void_v<Result>) {
            {
                py::gil_scoped_release release;
                work();
            }
            bridge.rethrow_if_failed();
        } else {
            Result result = [&] {
                py::gil_scoped_release release;
                return work();
            }();
            bridge.rethrow_if_failed();
            return result;
        }
    } catch (const py::error_already_set&) {
        throw;
    } catch (...) {
        bridge.rethrow_if_failed();
        throw;
    }
}

/// The PointCloud objects of a Python sequence (TypeError naming the first item that is none).
std::vector<PointCloud*> views_of(const py::handle& sequence, const char* function);

/// Moves the views out of their Python objects for a call that takes a vector of views, and back
/// when it ends (also on an exception): no copy of the points.
class BorrowedViews {
public:
    explicit BorrowedViews(std::vector<PointCloud*> owners);
    ~BorrowedViews();
    BorrowedViews(const BorrowedViews&) = delete;
    BorrowedViews& operator=(const BorrowedViews&) = delete;
    std::vector<PointCloud>& views() { return views_; }

private:
    std::vector<PointCloud*> owners_;
    std::vector<PointCloud> views_;
};

/// A Report as a Python object (dict, list, numbers, strings; NaN as None).
py::object to_python(const Report& report);

/// A capture argument: an opened Capture, or a path opened with io::open_capture.
io::Capture capture_of(const py::object& capture);

/// The frames a tool selects with --frameset / --frames / --sensors (cli::select_frames, so
/// that the same capture gives the same views here and in the tools).
std::vector<std::pair<std::string, std::size_t>> selected_frames(
    const io::Capture& capture, long long frameset, const std::string& frames,
    const std::vector<std::string>& sensors);

/// The `noise_model` option: "auto" -> nullopt, else the named model (InputError naming the
/// valid ones).
std::optional<denoise::NoiseModel> noise_model_option(Options& options);

/// Registers the pipeline stages on the module (bindings_stages.cpp).
void bind_stages(py::module_& m);

/// Registers texture(), evaluate(), evaluate_poses() and reconstruct() (bindings_results.cpp).
void bind_results(py::module_& m);

}  // namespace rgbd::python
