// The compiled part of the Python module rgbd_toolkit (docs/python.md): the data types (views as
// PointCloud, Mesh, the capture folder's rig and frame lists) with numpy accessors, the readers
// and writers of io/, and the toolkit's errors as Python exceptions. The stages are in
// bindings_stages.cpp. A thin layer: every computation is a call into the toolkit's libraries.
#include "python/bindings.hpp"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>

#include "io/capture_folder.hpp"
#include "io/mesh_io.hpp"
#include "io/ply_stream.hpp"
#include "pipeline/stages.hpp"
#include "toolkit/error.hpp"

namespace rgbd::python {

// ---- helpers shared with bindings_stages.cpp -------------------------------------------------

Options::Options(std::string function, const py::kwargs& kwargs)
    : function_(std::move(function)), kwargs_(kwargs) {}

bool Options::flag(const char* name) {
    bool value = false;
    get(name, value);
    return value;
}

py::object Options::object(const char* name) {
    known_.insert(name);
    return kwargs_.contains(name) ? py::reinterpret_borrow<py::object>(kwargs_[name]) : py::none();
}

void Options::done() const {
    for (const auto& item : kwargs_) {
        const std::string key = py::str(item.first);
        if (known_.count(key)) continue;
        std::string valid;
        for (const auto& k : known_) valid += (valid.empty() ? "" : ", ") + k;
        throw py::type_error(function_ + "() got an unexpected keyword argument '" + key +
                             "' (options: " + valid + ")");
    }
}

ProgressBridge::ProgressBridge(py::object callback) : callback_(std::move(callback)) {
    if (!callback_.is_none() && !PyCallable_Check(callback_.ptr()))
        throw py::type_error("progress must be callable: progress(stage, fraction)");
}

Progress ProgressBridge::stage(const std::string& name) {
    if (callback_.is_none()) return {};
    // Captures raw pointers only: the Progress is copied inside the toolkit without the GIL.
    PyObject* callback = callback_.ptr();
    ProgressBridge* self = this;
    return [callback, self, name](double fraction) {
        py::gil_scoped_acquire gil;
        if (*self->error_) return false;
        try {
            py::object result = py::reinterpret_borrow<py::object>(callback)(name, fraction);
            return result.is_none() || result.cast<bool>();
        } catch (...) {
            self->fail();
            return false;
        }
    };
}

void ProgressBridge::fail() {
    if (!*error_) *error_ = std::current_exception();
}

void ProgressBridge::rethrow_if_failed() const {
    if (*error_) std::rethrow_exception(*error_);
}

std::vector<PointCloud*> views_of(const py::handle& sequence, const char* function) {
    if (!py::isinstance<py::sequence>(sequence) || py::isinstance<py::str>(sequence))
        throw py::type_error(std::string(function) + "(): views must be a list of PointCloud");
    std::vector<PointCloud*> views;
    const auto list = py::reinterpret_borrow<py::sequence>(sequence);
    for (std::size_t i = 0; i < list.size(); ++i) {
        py::object item = list[i];
        if (!py::isinstance<PointCloud>(item))
            throw py::type_error(
                std::string(function) + "(): views[" + std::to_string(i) + "] is a " +
                std::string(py::str(py::type::of(item).attr("__name__"))) + ", not a PointCloud");
        views.push_back(item.cast<PointCloud*>());
    }
    return views;
}

BorrowedViews::BorrowedViews(std::vector<PointCloud*> owners) : owners_(std::move(owners)) {
    views_.reserve(owners_.size());
    for (PointCloud* owner : owners_) views_.push_back(std::move(*owner));
}

BorrowedViews::~BorrowedViews() {
    for (std::size_t i = 0; i < owners_.size() && i < views_.size(); ++i)
        *owners_[i] = std::move(views_[i]);
}

py::object to_python(const Report& report) {
    return py::module_::import("json").attr("loads")(report.dump());
}

namespace {

// ---- numpy conversions ------------------------------------------------------------------------

using Doubles = py::array_t<double, py::array::c_style | py::array::forcecast>;
using Bytes = py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>;

static_assert(sizeof(Point_3) == 3 * sizeof(double) && sizeof(Vector_3) == 3 * sizeof(double),
              "Point_3 and Vector_3 are three packed doubles (the mesh's zero-copy vertices)");

/// Checks that `a` is N x 3 (N = `rows` unless rows < 0); InputError naming `what` otherwise.
void check_rows3(const py::array& a, const std::string& what, long long rows = -1) {
    std::ostringstream shape;
    shape << "(";
    for (py::ssize_t d = 0; d < a.ndim(); ++d) shape << (d ? ", " : "") << a.shape(d);
    shape << (a.ndim() == 1 ? ",)" : ")");
    RGBD_CHECK(a.ndim() == 2 && a.shape(1) == 3,
               what + " must be an N x 3 array, got shape " + shape.str());
    RGBD_CHECK(rows < 0 || a.shape(0) == rows, what + " has " + std::to_string(a.shape(0)) +
                                                   " rows, the cloud " + std::to_string(rows) +
                                                   " points");
}

/// Checks that every value of `a` is finite; InputError naming the first bad row.
void check_finite(const Doubles& a, const std::string& what) {
    const double* data = a.data();
    for (py::ssize_t i = 0; i < a.size(); ++i)
        RGBD_CHECK(std::isfinite(data[i]),
                   what + ": row " + std::to_string(i / 3) + " is not finite (NaN or infinity)");
}

/// An integer colour array as uint8, refusing values outside 0..255 (a float array in [0, 1]
/// would be silently black otherwise).
Bytes colours_of(const py::array& input, long long rows) {
    check_rows3(input, "colors", rows);
    const Doubles values = Doubles::ensure(input);
    RGBD_CHECK(values, "colors must be numeric");
    for (py::ssize_t i = 0; i < values.size(); ++i) {
        const double c = values.data()[i];
        RGBD_CHECK(c >= 0 && c <= 255 && c == std::floor(c),
                   "colors must be integers in 0..255 (uint8 RGB), got " + format_number(c) +
                       " in row " + std::to_string(i / 3));
    }
    return Bytes::ensure(input);
}

py::array_t<double> pose_to_numpy(const Pose& pose) {
    py::array_t<double> out({4, 4});
    auto m = out.mutable_unchecked<2>();
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) m(r, c) = pose.matrix()(r, c);
    return out;
}

Pose pose_from_numpy(const py::array& input, const std::string& what) {
    const Doubles a = Doubles::ensure(input);
    RGBD_CHECK(a && a.ndim() == 2 && a.shape(0) == 4 && a.shape(1) == 4,
               what + " must be a 4 x 4 array");
    std::array<double, 16> v{};
    for (int i = 0; i < 16; ++i) {
        v[i] = a.data()[i];
        RGBD_CHECK(std::isfinite(v[i]), what + " is not finite");
    }
    return pose_from_4x4(v);
}

py::object optional_pose(const std::optional<Pose>& pose) {
    return pose ? py::object(pose_to_numpy(*pose)) : py::object(py::none());
}

// ---- PointCloud -------------------------------------------------------------------------------

py::array_t<double> cloud_points(const PointCloud& cloud) {
    py::array_t<double> out({static_cast<py::ssize_t>(cloud.size()), py::ssize_t{3}});
    double* d = out.mutable_data();
    for (auto i : cloud.points) {
        const Point_3& p = cloud.points.point(i);
        *d++ = p.x();
        *d++ = p.y();
        *d++ = p.z();
    }
    return out;
}

py::object cloud_normals(const PointCloud& cloud) {
    if (!cloud.points.has_normal_map()) return py::none();
    py::array_t<double> out({static_cast<py::ssize_t>(cloud.size()), py::ssize_t{3}});
    double* d = out.mutable_data();
    for (auto i : cloud.points) {
        const Vector_3& n = cloud.points.normal(i);
        *d++ = n.x();
        *d++ = n.y();
        *d++ = n.z();
    }
    return out;
}

py::object cloud_colors(const PointCloud& cloud) {
    if (!cloud.has_colors()) return py::none();
    const auto maps = cloud.colors();
    py::array_t<std::uint8_t> out({static_cast<py::ssize_t>(cloud.size()), py::ssize_t{3}});
    std::uint8_t* d = out.mutable_data();
    for (auto i : cloud.points) {
        const Rgb c = maps.get(i);
        *d++ = c.r;
        *d++ = c.g;
        *d++ = c.b;
    }
    return out;
}

void set_points(PointCloud& cloud, const py::array& input) {
    check_rows3(input, "points", static_cast<long long>(cloud.size()));
    const Doubles a = Doubles::ensure(input);
    check_finite(a, "points");
    const double* d = a.data();
    for (auto i : cloud.points) {
        cloud.points.point(i) = Point_3(d[0], d[1], d[2]);
        d += 3;
    }
}

void set_normals(PointCloud& cloud, const py::object& input) {
    if (input.is_none()) {
        if (cloud.points.has_normal_map()) cloud.points.remove_normal_map();
        return;
    }
    check_rows3(input.cast<py::array>(), "normals", static_cast<long long>(cloud.size()));
    const Doubles a = Doubles::ensure(input);
    check_finite(a, "normals");
    cloud.points.add_normal_map();
    const double* d = a.data();
    for (auto i : cloud.points) {
        cloud.points.normal(i) = Vector_3(d[0], d[1], d[2]);
        d += 3;
    }
}

void set_colors(PointCloud& cloud, const py::object& input) {
    if (input.is_none()) {
        for (const char* name : {prop::kRed, prop::kGreen, prop::kBlue})
            if (auto [map, found] = cloud.points.property_map<std::uint8_t>(name); found)
                cloud.points.remove_property_map(map);
        return;
    }
    const Bytes a = colours_of(input.cast<py::array>(), static_cast<long long>(cloud.size()));
    const auto maps = cloud.add_colors();
    const std::uint8_t* d = a.data();
    for (auto i : cloud.points) {
        maps.set(i, {d[0], d[1], d[2]});
        d += 3;
    }
}

PointCloud make_cloud(const py::array& points, const py::object& normals, const py::object& colors,
                      const py::object& pose) {
    check_rows3(points, "points");
    PointCloud cloud;
    cloud.points.resize(static_cast<std::size_t>(points.shape(0)));
    set_points(cloud, points);
    set_normals(cloud, normals);
    set_colors(cloud, colors);
    if (!pose.is_none()) cloud.view.world_from_sensor = pose_from_numpy(pose, "pose");
    return cloud;
}

/// One property of the point set by name as a numpy copy (uint8, uint32, int32 or float).
py::object cloud_property(const PointCloud& cloud, const std::string& name) {
    auto copy = [&](auto map) {
        using T = std::decay_t<decltype(map[*cloud.points.begin()])>;
        py::array_t<T> out(static_cast<py::ssize_t>(cloud.size()));
        T* d = out.mutable_data();
        for (auto i : cloud.points) *d++ = map[i];
        return py::object(out);
    };
    if (auto [m, found] = cloud.points.property_map<std::uint8_t>(name); found) return copy(m);
    if (auto [m, found] = cloud.points.property_map<std::uint32_t>(name); found) return copy(m);
    if (auto [m, found] = cloud.points.property_map<std::int32_t>(name); found) return copy(m);
    if (auto [m, found] = cloud.points.property_map<float>(name); found) return copy(m);
    throw InputError("the cloud has no property '" + name + "'");
}

std::string cloud_repr(const PointCloud& cloud) {
    std::ostringstream s;
    s << "<rgbd_toolkit.PointCloud view " << cloud.view.id << " sensor '" << cloud.view.sensor
      << "', " << cloud.size() << " points, "
      << (cloud.view.frame == ViewFrame::kWorld ? "world" : "sensor") << " frame>";
    return s.str();
}

// ---- Mesh -------------------------------------------------------------------------------------

/// The vertices without a copy (read-only, kept alive by the mesh object) when the mesh has no
/// removed elements, else a copy in vertex order.
py::array mesh_vertices(py::object self) {
    const Mesh& mesh = self.cast<const Mesh&>();
    const auto n = static_cast<py::ssize_t>(mesh.number_of_vertices());
    if (!mesh.has_garbage() && n > 0) {
        const double* data = reinterpret_cast<const double*>(&mesh.point(Mesh::Vertex_index(0)));
        py::array out(py::dtype::of<double>(), {n, py::ssize_t{3}},
                      {py::ssize_t(sizeof(Point_3)), py::ssize_t(sizeof(double))}, data, self);
        py::detail::array_proxy(out.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
        return out;
    }
    py::array_t<double> out({n, py::ssize_t{3}});
    double* d = out.mutable_data();
    for (const auto v : mesh.vertices()) {
        const Point_3& p = mesh.point(v);
        *d++ = p.x();
        *d++ = p.y();
        *d++ = p.z();
    }
    return out;
}

/// Position of each vertex in vertices() order (identity without garbage).
std::vector<std::int64_t> vertex_positions(const Mesh& mesh) {
    std::vector<std::int64_t> position(mesh.num_vertices(), -1);
    std::int64_t next = 0;
    for (const auto v : mesh.vertices()) position[v.idx()] = next++;
    return position;
}

py::array_t<std::int64_t> mesh_faces(const Mesh& mesh) {
    const auto position = vertex_positions(mesh);
    py::array_t<std::int64_t> out(
        {static_cast<py::ssize_t>(mesh.number_of_faces()), py::ssize_t{3}});
    std::int64_t* d = out.mutable_data();
    for (const auto f : mesh.faces()) {
        int corners = 0;
        for (const auto v : CGAL::vertices_around_face(mesh.halfedge(f), mesh)) {
            RGBD_CHECK(corners < 3, "the mesh has a face with more than three corners");
            *d++ = position[v.idx()];
            ++corners;
        }
        RGBD_CHECK(corners == 3, "the mesh has a face with fewer than three corners");
    }
    return out;
}

py::object mesh_colors(const Mesh& mesh) {
    const auto map = vertex_colors(mesh);
    if (!map) return py::none();
    py::array_t<std::uint8_t> out(
        {static_cast<py::ssize_t>(mesh.number_of_vertices()), py::ssize_t{3}});
    std::uint8_t* d = out.mutable_data();
    for (const auto v : mesh.vertices()) {
        const MeshColor& c = (*map)[v];
        *d++ = c.red();
        *d++ = c.green();
        *d++ = c.blue();
    }
    return out;
}

py::object mesh_normals(const Mesh& mesh) {
    auto [map, found] = mesh.property_map<Mesh::Vertex_index, Vector_3>(kVertexNormal);
    if (!found) return py::none();
    py::array_t<double> out({static_cast<py::ssize_t>(mesh.number_of_vertices()), py::ssize_t{3}});
    double* d = out.mutable_data();
    for (const auto v : mesh.vertices()) {
        const Vector_3& n = map[v];
        *d++ = n.x();
        *d++ = n.y();
        *d++ = n.z();
    }
    return out;
}

Mesh make_mesh(const py::array& vertices, const py::array& faces, const py::object& colors) {
    check_rows3(vertices, "vertices");
    const Doubles v = Doubles::ensure(vertices);
    check_finite(v, "vertices");
    check_rows3(faces, "faces");
    RGBD_CHECK(
        py::dtype::of<std::int64_t>().kind() == faces.dtype().kind() || faces.dtype().kind() == 'u',
        "faces must be an integer array");
    const auto f =
        py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(faces);
    Mesh mesh;
    const auto n = static_cast<std::int64_t>(v.shape(0));
    for (std::int64_t i = 0; i < n; ++i)
        mesh.add_vertex(Point_3(v.data()[3 * i], v.data()[3 * i + 1], v.data()[3 * i + 2]));
    for (py::ssize_t i = 0; i < f.shape(0); ++i) {
        std::array<Mesh::Vertex_index, 3> corner;
        for (int k = 0; k < 3; ++k) {
            const std::int64_t index = f.data()[3 * i + k];
            RGBD_CHECK(index >= 0 && index < n, "faces: row " + std::to_string(i) +
                                                    " names vertex " + std::to_string(index) +
                                                    " of " + std::to_string(n));
            corner[k] = Mesh::Vertex_index(static_cast<std::uint32_t>(index));
        }
        RGBD_CHECK(
            mesh.add_face(corner[0], corner[1], corner[2]) != Mesh::null_face(),
            "faces: row " + std::to_string(i) + " cannot be added (degenerate or non-manifold)");
    }
    if (!colors.is_none()) {
        const Bytes c = colours_of(colors.cast<py::array>(), n);
        auto map = add_vertex_colors(mesh);
        for (std::int64_t i = 0; i < n; ++i)
            map[Mesh::Vertex_index(static_cast<std::uint32_t>(i))] =
                MeshColor(c.data()[3 * i], c.data()[3 * i + 1], c.data()[3 * i + 2]);
    }
    return mesh;
}

// ---- readers and writers ----------------------------------------------------------------------

std::vector<PointCloud> read_views(const std::filesystem::path& path) {
    pipeline::LoadedResult loaded = pipeline::load_result(path.string());
    RGBD_CHECK(!loaded.mesh, path.string() + ": holds a mesh, not views (read it with read_mesh)");
    return std::move(loaded.views);
}

void write_views(const py::handle& views, const std::filesystem::path& path) {
    const auto clouds = views_of(views, "write_views");
    std::ostringstream out;
    for (const PointCloud* cloud : clouds) io::write_points(out, *cloud);
    const std::string bytes = out.str();
    io::write_bytes_atomic(path, reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
}

void save_mesh(const Mesh& mesh, const std::filesystem::path& path) {
    ViewInfo info;
    info.frame = ViewFrame::kWorld;
    info.sensor = "mesh";
    io::write_mesh(path, mesh, &info);
}

py::dict intrinsics_dict(const PinholeIntrinsics& k) {
    py::dict d;
    d["width"] = k.width;
    d["height"] = k.height;
    d["fx"] = k.fx;
    d["fy"] = k.fy;
    d["cx"] = k.cx;
    d["cy"] = k.cy;
    return d;
}

}  // namespace

}  // namespace rgbd::python

PYBIND11_MODULE(_rgbd_toolkit, m) {
    using namespace rgbd;
    using namespace rgbd::python;
    using namespace pybind11::literals;
    m.doc() =
        "rgbd-toolkit's library from Python: capture folders, views and meshes as numpy arrays, "
        "the pipeline stages with the tools' options and defaults (docs/python.md).";

    // The toolkit's errors, with their messages: InputError is a ValueError, IoError an
    // OSError, AlgorithmError a RuntimeError.
    py::register_exception<InputError>(m, "InputError", PyExc_ValueError);
    py::register_exception<IoError>(m, "IoError", PyExc_OSError);
    py::register_exception<AlgorithmError>(m, "AlgorithmError", PyExc_RuntimeError);

    py::class_<PointCloud>(m, "PointCloud",
                           "One view: points (N x 3, metres) with optional normals and RGB "
                           "colours, and the view's metadata (id, sensor, frame, pose). The "
                           "array properties return copies (the stages modify views in place, "
                           "so a view into their storage would dangle); assign to set them.")
        .def(py::init(&make_cloud), "points"_a, "normals"_a = py::none(), "colors"_a = py::none(),
             "pose"_a = py::none(),
             "A view from an N x 3 point array, optional N x 3 normals, N x 3 uint8 RGB colours "
             "and a 4 x 4 world_from_sensor pose. Raises ValueError for wrong shapes or NaN.")
        .def("__len__", &PointCloud::size)
        .def("__repr__", &cloud_repr)
        .def(
            "copy", [](const PointCloud& c) { return PointCloud(c); }, "A deep copy.")
        .def_property("points", &cloud_points, &set_points, "N x 3 float64 (a copy)")
        .def_property("normals", &cloud_normals, &set_normals, "N x 3 float64 or None (a copy)")
        .def_property("colors", &cloud_colors, &set_colors, "N x 3 uint8 RGB or None (a copy)")
        .def_property(
            "pose", [](const PointCloud& c) { return optional_pose(c.view.world_from_sensor); },
            [](PointCloud& c, const py::object& pose) {
                if (pose.is_none())
                    c.view.world_from_sensor.reset();
                else
                    c.view.world_from_sensor = pose_from_numpy(pose, "pose");
            },
            "world_from_sensor as a 4 x 4 float64 array, or None")
        .def_property(
            "frame",
            [](const PointCloud& c) {
                return std::string(c.view.frame == ViewFrame::kWorld ? "world" : "sensor");
            },
            [](PointCloud& c, const std::string& frame) {
                RGBD_CHECK(frame == "world" || frame == "sensor",
                           "frame must be 'sensor' or 'world', not '" + frame + "'");
                c.view.frame = frame == "world" ? ViewFrame::kWorld : ViewFrame::kSensor;
            },
            "'sensor' (points in the sensor frame, pose maps them to the world) or 'world'")
        .def_property(
            "id", [](const PointCloud& c) { return c.view.id; },
            [](PointCloud& c, int id) { c.view.id = id; }, "view id (-1 = unset)")
        .def_property(
            "sensor", [](const PointCloud& c) { return c.view.sensor; },
            [](PointCloud& c, const std::string& s) { c.view.sensor = s; }, "sensor id")
        .def_property_readonly(
            "frame_index", [](const PointCloud& c) { return c.view.frame_index; },
            "index of the source frame in frames.csv, or None")
        .def_property_readonly(
            "source", [](const PointCloud& c) { return c.view.source; }, "source frame's path")
        .def_property_readonly(
            "grid",
            [](const PointCloud& c) -> py::object {
                if (!c.view.has_grid()) return py::none();
                return py::make_tuple(c.view.grid_width, c.view.grid_height);
            },
            "(width, height) of the pixel grid of an organised view, or None")
        .def_property_readonly(
            "intrinsics",
            [](const PointCloud& c) -> py::object {
                if (!c.view.intrinsics) return py::none();
                return intrinsics_dict(*c.view.intrinsics);
            },
            "the depth camera's pinhole intrinsics as a dict, or None")
        .def_property_readonly(
            "comments", [](const PointCloud& c) { return c.view.extra_comments; },
            "metadata lines the toolkit keeps verbatim (noise model, stand plane...)")
        .def("property_names", &PointCloud::property_names,
             "Names of the per-point properties besides point and normal.")
        .def("property", &cloud_property, "name"_a,
             "One per-point property (e.g. 'pixel', 'noise', 'synthetic') as a numpy copy.");

    py::class_<Mesh>(m, "Mesh", py::dynamic_attr(),
                     "A triangle mesh: vertices (N x 3 float64, metres, read-only and without a "
                     "copy), faces (M x 3 int64, a copy) and optional per-vertex RGB colours. "
                     "Meshes from reconstruct() carry its report as the attribute `report`.")
        .def(py::init(&make_mesh), "vertices"_a, "faces"_a, "colors"_a = py::none(),
             "A mesh from N x 3 vertices, M x 3 vertex indices and optional N x 3 uint8 "
             "colours. Raises ValueError for wrong shapes, NaN, indices out of range or "
             "non-manifold faces.")
        .def_property_readonly("vertices", &mesh_vertices)
        .def_property_readonly("faces", &mesh_faces)
        .def_property_readonly("colors", &mesh_colors)
        .def_property_readonly("normals", &mesh_normals)
        .def("save", &save_mesh, "path"_a,
             "Writes .ply (binary, with colours), .off or .obj, atomically (as the tools do).")
        .def("__repr__", [](const Mesh& mesh) {
            return "<rgbd_toolkit.Mesh " + std::to_string(mesh.number_of_vertices()) +
                   " vertices, " + std::to_string(mesh.number_of_faces()) + " faces>";
        });

    py::class_<io::SensorSpec>(m, "Sensor", "One sensor of the capture's rig.json.")
        .def_readonly("id", &io::SensorSpec::id)
        .def_readonly("model", &io::SensorSpec::model)
        .def_property_readonly("depth_intrinsics",
                               [](const io::SensorSpec& s) { return intrinsics_dict(s.depth); })
        .def_property_readonly("color_intrinsics",
                               [](const io::SensorSpec& s) { return intrinsics_dict(s.color); })
        .def_readonly("depth_scale", &io::SensorSpec::depth_scale)
        .def_readonly("range_min_m", &io::SensorSpec::range_min_m)
        .def_readonly("range_max_m", &io::SensorSpec::range_max_m)
        .def_property_readonly(
            "world_from_depth",
            [](const io::SensorSpec& s) {
                return s.has_world_from_depth ? py::object(pose_to_numpy(s.world_from_depth))
                                              : py::object(py::none());
            },
            "4 x 4 pose, or None when the layout has none")
        .def_property_readonly(
            "color_from_depth",
            [](const io::SensorSpec& s) { return pose_to_numpy(s.color_from_depth); })
        .def_readonly("noise_model", &io::SensorSpec::noise_model)
        .def("__repr__",
             [](const io::SensorSpec& s) { return "<rgbd_toolkit.Sensor " + s.id + ">"; });

    py::class_<io::FrameRecord>(m, "Frame", "One line of a sensor's frames.csv.")
        .def_readonly("index", &io::FrameRecord::index)
        .def_readonly("time_ns", &io::FrameRecord::time_ns)
        .def_readonly("depth", &io::FrameRecord::depth)
        .def_readonly("color", &io::FrameRecord::color)
        .def_readonly("mask", &io::FrameRecord::mask)
        .def_property_readonly("world_from_depth", [](const io::FrameRecord& f) {
            return optional_pose(f.world_from_depth);
        });

    py::class_<io::FrameSet>(m, "FrameSet", "One line of framesets.csv.")
        .def_readonly("set", &io::FrameSet::set)
        .def_readonly("time_ns", &io::FrameSet::time_ns)
        .def_readonly("spread_ns", &io::FrameSet::spread_ns)
        .def_readonly("frames", &io::FrameSet::frames,
                      "frame index per sensor, in rig order (-1 = missing)");

    py::class_<io::Capture>(m, "Capture",
                            "An opened capture folder: the rig (sensors with intrinsics and "
                            "poses), the frame lists and the frame sets. Images are read by the "
                            "stages.")
        .def_property_readonly("root", [](const io::Capture& c) { return c.root.string(); })
        .def_readonly("layout", &io::Capture::layout)
        .def_property_readonly("sensors", [](const io::Capture& c) { return c.rig.sensors; })
        .def_readonly("frames", &io::Capture::frames, "{sensor id: [Frame, ...]}")
        .def_readonly("framesets", &io::Capture::framesets)
        .def("__repr__", [](const io::Capture& c) {
            return "<rgbd_toolkit.Capture " + c.root.string() + " (" + c.layout + ", " +
                   std::to_string(c.rig.sensors.size()) + " sensors, " +
                   std::to_string(c.framesets.size()) + " frame sets)>";
        });

    m.def(
        "read_capture",
        [](const std::filesystem::path& path) {
            py::gil_scoped_release release;
            return io::open_capture(path);
        },
        "path"_a,
        "Opens a capture folder (capture folder v1, TUM, Redwood, ...; io::open_capture). "
        "Raises ValueError / OSError naming the file for a missing or malformed folder.");
    m.def(
        "read_views",
        [](const std::filesystem::path& path) {
            py::gil_scoped_release release;
            return read_views(path);
        },
        "path"_a,
        "Reads the views of a view stream (.ply, the pipe format) or a point file (.pcd, .xyz) "
        "as a list of PointCloud.");
    m.def("write_views", &write_views, "views"_a, "path"_a,
          "Writes views as a view stream (.ply, the pipe format the tools read), atomically.");
    m.def(
        "read_mesh",
        [](const std::filesystem::path& path) {
            py::gil_scoped_release release;
            return io::read_mesh(path);
        },
        "path"_a, "Reads a triangle mesh (.ply, .off, .obj).");

    bind_stages(m);
    bind_results(m);
}
