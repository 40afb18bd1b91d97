// The Python module `prtbake` (its compiled part, prtbake._prtbake): the library's products
// with NumPy arrays in and out. Each product's keyword arguments are its job type's keys
// (service/job_types.cpp), checked by the same declaration as the command line and job files,
// so that a keyword takes exactly the values `--option` takes. Results are NumPy arrays that
// own the library's vectors (moved, not copied). The GIL is released while the library works;
// calls on one device are serialised (a Runtime's kernels are shared), calls on two devices
// run at once.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "jobs.h"
#include "options.h"
#include "prtbake/clock.h"
#include "prtbake/env.h"
#include "prtbake/error.h"
#include "prtbake/exr.h"
#include "prtbake/glossy.h"
#include "prtbake/ibl.h"
#include "prtbake/lut.h"
#include "prtbake/mesh.h"
#include "prtbake/preview.h"
#include "prtbake/prefilter.h"
#include "prtbake/progress.h"
#include "prtbake/runtime.h"
#include "prtbake/sh_rotate.h"
#include "prtbake/lightmap.h"
#include "prtbake/probes.h"
#include "prtbake/transport.h"
#include "confine.h"
#include "runner.h"

namespace py = pybind11;
using nlohmann::json;

namespace prtbake::python {
namespace {

// --- devices: one runtime per device spec (the process's, as the command uses), one lock each ---

struct Device {
  Runtime& rt;
  std::unique_lock<std::mutex> lock;
};

// The runtime of `spec` ("" : $PRTBAKE_DEVICE or auto), locked for this call. Call without the GIL.
Device device(const std::string& spec) {
  static std::mutex mapMutex;
  static auto* const locks = new std::map<std::string, std::mutex>();  // never destroyed, as the runtimes
  std::mutex* m;
  {
    std::lock_guard<std::mutex> g(mapMutex);
    m = &(*locks)[spec];
  }
  std::unique_lock<std::mutex> lock(*m);
  return {jobs::processRuntime(spec), std::move(lock)};
}

// --- progress and Ctrl-C ---

// The progress hook of a call that runs without the GIL (prtbake/progress.h): at each of the
// library's checkpoints it runs Python's signal handlers (Ctrl-C raises KeyboardInterrupt) and
// calls `progress(stage, fraction)` when given; either raising stops the call, and the Python
// exception is raised when the call returns (the Cancelled translator leaves it in place).
// `progress` is borrowed: the call's keyword arguments hold it.
ProgressHook pythonHook(PyObject* progress) {
  // Without a progress function the hook only looks for Ctrl-C, at most every kSignalCheck
  // seconds: a short call never takes the GIL back before it ends.
  constexpr double kSignalCheck = 0.05;
  auto last = std::make_shared<std::chrono::steady_clock::time_point>(std::chrono::steady_clock::now());
  return [progress, last](const std::string& stage, double fraction) {
    if (!progress && secondsSince(*last) < kSignalCheck) return true;
    *last = std::chrono::steady_clock::now();
    py::gil_scoped_acquire gil;
    if (PyErr_Occurred() || PyErr_CheckSignals() != 0) return false;
    if (progress) {
      try {
        py::reinterpret_borrow<py::object>(progress)(stage, fraction);
      } catch (py::error_already_set& e) {
        e.restore();
        return false;
      }
    }
    return true;
  };
}

// The keyword `progress`: a callable or None.
PyObject* progressOf(const py::kwargs& kwargs) {
  if (!kwargs.contains("progress") || kwargs["progress"].is_none()) return nullptr;
  py::object p = kwargs["progress"];
  if (!PyCallable_Check(p.ptr())) throw UsageError("progress", "must be a callable progress(stage, fraction) or None");
  return p.ptr();
}

// --- values between Python and JSON ---

json toJson(const py::handle& v, const std::string& key) {
  if (py::isinstance<py::bool_>(v)) return v.cast<bool>();
  if (py::isinstance<py::int_>(v)) return v.cast<long long>();
  if (py::isinstance<py::float_>(v)) return v.cast<double>();
  if (py::isinstance<py::str>(v)) return v.cast<std::string>();
  if (py::hasattr(v, "__fspath__")) return py::str(v.attr("__fspath__")()).cast<std::string>();
  if (py::isinstance<py::sequence>(v)) {
    json a = json::array();
    for (const py::handle& x : v.cast<py::sequence>()) a.push_back(toJson(x, key));
    return a;
  }
  if (py::hasattr(v, "item")) return toJson(v.attr("item")(), key);  // NumPy scalars
  throw UsageError(key, "cannot take a value of type " + py::str(py::type::of(v).attr("__name__")).cast<std::string>());
}

py::object fromJson(const json& j) { return py::module_::import("json").attr("loads")(j.dump()); }

// A product's parameters from keyword arguments, checked as a job file's or a command line's
// are (UsageError naming the key: ValueError in Python). `outputs` are what the call makes,
// for the cross-key rules that depend on them.
json paramsOf(const std::string& typeName, const py::kwargs& kwargs, const json& outputs,
              const std::vector<std::string>& own = {}) {
  const jobs::JobType* type = jobs::findJobType(typeName);
  if (!type) throw UsageError(typeName, "no such product");
  json given = json::object();
  for (const auto& [k, v] : kwargs) {
    const std::string name = py::str(k).cast<std::string>();
    if (std::find(own.begin(), own.end(), name) != own.end()) continue;
    const auto spec = std::find_if(type->keys.begin(), type->keys.end(),
                                   [&](const jobs::KeySpec& s) { return s.name == name && s.onCommandLine; });
    if (spec == type->keys.end()) {
      std::string names;
      for (const auto& s : type->keys)
        if (s.onCommandLine) names += (names.empty() ? "" : ", ") + s.name;
      throw UsageError(name, "not a keyword of " + typeName + " (its keywords: " + names + ")");
    }
    if (!v.is_none()) given[name] = toJson(v, name);
  }
  jobs::KeyProblems problems;
  json params = jobs::normalise(type->keys, given, &problems);
  if (problems.empty() && type->check) {
    json raw = given;
    raw["outputs"] = outputs;
    problems = type->check(raw, params);
  }
  if (!problems.empty()) throw UsageError(problems.front().first, problems.front().second);
  return params;
}

std::string deviceOf(const py::kwargs& kwargs) {
  if (kwargs.contains("device") && !kwargs["device"].is_none()) return kwargs["device"].cast<std::string>();
  return "";
}

// --- arrays: the library's vectors handed to NumPy without a copy ---

template <class V>
py::array adopt(V&& values, const std::vector<py::ssize_t>& shape) {
  using T = typename std::decay_t<V>::value_type;
  auto* owned = new std::decay_t<V>(std::move(values));
  py::capsule owner(owned, [](void* p) { delete static_cast<std::decay_t<V>*>(p); });
  return py::array_t<T>(shape, owned->data(), owner);
}

// SH coefficients as a (n², 3) float64 array.
py::array shArray(const ShCoeffs& c) {
  std::vector<double> v;
  v.reserve(c.rgb.size() * 3);
  for (const Rgb& x : c.rgb) v.insert(v.end(), x.begin(), x.end());
  return adopt(std::move(v), {py::ssize_t(c.rgb.size()), 3});
}

ShCoeffs shFromArray(const py::array_t<double, py::array::c_style | py::array::forcecast>& a) {
  const py::ssize_t n = a.ndim() == 2 && a.shape(1) == 3 ? a.shape(0) : -1;
  int order = 0;
  while (order * order < n) ++order;
  if (n < 1 || order * order != n || order > kMaxShOrder)
    throw UsageError("coeffs", "must be an (n², 3) array of SH coefficients, n = 1.." + std::to_string(kMaxShOrder));
  ShCoeffs c;
  c.order = order;
  c.rgb.resize(size_t(n));
  std::memcpy(c.rgb.data(), a.data(), size_t(n) * 3 * sizeof(double));
  return c;
}

// A Python result: prtbake.<name>(**fields), a plain namespace class of __init__.py.
py::object result(const char* name, py::dict fields) {
  // The package, looked up once (an import per call was ~2 µs of a small call's overhead) and
  // held for the process's life, as Python holds it in sys.modules.
  static const py::handle package = py::module_::import("prtbake").release();
  return package.attr(name)(**fields);
}

// --- inputs ---

bool isPath(const py::handle& v) { return py::isinstance<py::str>(v) || py::hasattr(v, "__fspath__"); }
std::string pathOf(const py::handle& v) {
  return py::isinstance<py::str>(v) ? v.cast<std::string>() : py::str(v.attr("__fspath__")()).cast<std::string>();
}

// A mesh argument: a prtbake.Mesh or a path.
// A path is loaded with the albedo the product reads (MeshAlbedo: textures only where it is used).
std::shared_ptr<const Mesh> meshArg(const py::object& v, MeshAlbedo albedo) {
  if (py::isinstance<Mesh>(v)) return v.cast<std::shared_ptr<Mesh>>();
  if (!isPath(v)) throw UsageError("mesh", "must be a prtbake.Mesh or the path of a .gltf, .glb or .obj file");
  const std::string path = pathOf(v);
  py::gil_scoped_release nogil;
  return std::make_shared<const Mesh>(loadMesh(path, albedo));
}

using FloatArray = py::array_t<float, py::array::c_style | py::array::forcecast>;

std::vector<float> rows3(const py::object& v, const char* name, py::ssize_t rows) {
  const FloatArray a = FloatArray::ensure(v);
  if (!a || a.ndim() != 2 || a.shape(1) != 3 || (rows >= 0 && a.shape(0) != rows))
    throw UsageError(name, rows >= 0 ? "must be a (" + std::to_string(rows) + ", 3) array" : "must be an (N, 3) array");
  return std::vector<float>(a.data(), a.data() + a.size());
}

// A mesh from arrays (read once into the library's layout; float32 C-order arrays are copied
// as they are, others converted).
std::shared_ptr<Mesh> meshFromArrays(const py::object& positions, const py::object& indices, const py::object& normals,
                                     const py::object& albedo, const py::object& uvs, const py::object& tangents) {
  auto mesh = std::make_shared<Mesh>();
  mesh->positions = rows3(positions, "positions", -1);
  const py::ssize_t nv = py::ssize_t(mesh->positions.size() / 3);
  using IndexArray = py::array_t<int64_t, py::array::c_style | py::array::forcecast>;
  const IndexArray idx = IndexArray::ensure(indices);
  if (!idx || idx.ndim() != 2 || idx.shape(1) != 3) throw UsageError("indices", "must be a (T, 3) integer array");
  if (py::isinstance<py::array>(indices) && py::array(indices).dtype().kind() == 'f')
    throw UsageError("indices", "must hold integers, not floats");
  mesh->indices.resize(size_t(idx.size()));
  for (py::ssize_t i = 0; i < idx.size(); ++i) {
    const int64_t k = idx.data()[i];
    if (k < 0 || k >= nv)
      throw InputError("mesh arrays", "index " + std::to_string(k) + " is out of range (" + std::to_string(nv) +
                                          " vertices)");
    mesh->indices[size_t(i)] = uint32_t(k);
  }
  mesh->normals = normals.is_none() ? std::vector<float>(size_t(3 * nv), 0.0f) : rows3(normals, "normals", nv);
  mesh->albedo = albedo.is_none() ? std::vector<float>(size_t(3 * nv), 1.0f) : rows3(albedo, "albedo", nv);
  if (!uvs.is_none()) {  // a sequence of (V, 2) arrays: UV set 0, 1, … (glTF's convention: v down)
    for (const py::handle set : uvs) {
      const FloatArray a = FloatArray::ensure(set);
      if (!a || a.ndim() != 2 || a.shape(1) != 2 || a.shape(0) != nv)
        throw UsageError("uvs", "each UV set must be a (" + std::to_string(nv) + ", 2) array");
      mesh->uvs.emplace_back(a.data(), a.data() + a.size());
      mesh->uvMissing.emplace_back();
    }
  }
  if (!tangents.is_none()) {  // (V, 4): xyz and w = ±1, glTF's TANGENT
    const FloatArray a = FloatArray::ensure(tangents);
    if (!a || a.ndim() != 2 || a.shape(1) != 4 || a.shape(0) != nv)
      throw UsageError("tangents", "must be a (" + std::to_string(nv) + ", 4) array (xyz, w = +1 or -1)");
    mesh->tangents.assign(a.data(), a.data() + a.size());
  }
  py::gil_scoped_release nogil;
  fillMissingNormals(*mesh);
  validateMesh(*mesh, "mesh arrays");
  return mesh;
}

// An environment argument as an EnvMap: a path (loaded as the commands load it) or an array,
// (H, 2H, 3) lat-long or (6, N, N, 3) cube faces in the order and orientation of
// docs/conventions.md "Cube faces". An array's texels are read in place (EnvMap::rgbView) when
// they are float32 and C-ordered, else from one converted copy; *keep holds whichever array
// the map points into, and must outlive it.
EnvMap envArg(const py::object& source, const json& p, bool compact, py::object* keep) {
  EnvMap env;
  if (isPath(source)) {
    const std::string path = pathOf(source);
    const EnvLoadOptions lo = jobs::envLoadOptionsFrom(p, compact);
    py::gil_scoped_release nogil;
    env = loadEnvironment(path, lo);
  } else {
    const FloatArray a = FloatArray::ensure(source);
    if (!a) throw UsageError("environment", "must be a path or a float array");
    const bool cube = a.ndim() == 4 && a.shape(0) == 6 && a.shape(1) == a.shape(2) && a.shape(3) == 3;
    const bool latlong = a.ndim() == 3 && a.shape(1) == 2 * a.shape(0) && a.shape(2) == 3;
    if (!cube && !latlong)
      throw UsageError("environment", "an array must be (H, 2H, 3) lat-long or (6, N, N, 3) cube faces");
    const std::string layout = p["layout"].get<std::string>();
    if ((cube && layout != "auto" && layout != "faces") || (latlong && layout != "auto" && layout != "latlong"))
      throw UsageError("layout", layout + " does not match the array's shape");
    env.layout = cube ? EnvLayout::Cube : EnvLayout::LatLong;
    env.width = int(a.shape(1));
    env.height = int(cube ? a.shape(1) : a.shape(0));
    env.layoutName = cube ? "faces" : "latlong";
    env.source = "array";
    *keep = a;
    env.rgbView = a.data();
    validateEnvironment(env, p["clamp_invalid"].get<bool>());
  }
  env.yawDegrees = p["yaw"].get<double>();
  return env;
}

// --- products ---

py::object envProduct(const py::object& source, const py::kwargs& kw) {
  json p = paramsOf("env", kw, {{"json", "-"}}, {"device", "progress"});
  EnvProjectOptions po = jobs::envProjectOptionsFrom(p);
  const bool autoOrder = p["order"] == "auto";
  const std::string spec = deviceOf(kw);
  EnvMap env;
  py::object keep;  // an array the map reads in place
  EnvProjectResult r;
  json selection;
  const auto t0 = std::chrono::steady_clock::now();
  if (isPath(source)) {
    const std::string path = pathOf(source);
    const EnvLoadOptions lo = jobs::envLoadOptionsFrom(p, true);
    const double yaw = p["yaw"].get<double>();
    ProgressScope scope(pythonHook(progressOf(kw)));
    py::gil_scoped_release nogil;
    std::unique_ptr<Device> d;
    r = projectEnvironmentFile([&]() -> Runtime& {
          if (!d) d = std::make_unique<Device>(device(spec));
          return d->rt;
        }, path, lo, yaw, po, &env);
  } else {
    env = envArg(source, p, false, &keep);
    ProgressScope scope(pythonHook(progressOf(kw)));
    py::gil_scoped_release nogil;
    Device d = device(spec);
    r = projectEnvironment(d.rt, env, po);
  }
  if (autoOrder) selection = jobs::selectEnvOrder(r, po, p["tolerance"]);
  py::dict f;
  f["coeffs"] = shArray(r.coeffs);
  f["radiance"] = shArray(r.radiance);
  f["order"] = po.order;
  f["quantity"] = toString(po.quantity);
  f["window_weights"] = r.windowWeights;
  f["order_selection"] = autoOrder ? fromJson(selection) : py::none();
  f["layout"] = env.layoutName;
  f["width"] = env.width;
  f["height"] = env.height;
  f["texels"] = r.texels;
  f["clamped_texels"] = env.clampedTexels;
  f["kernel_seconds"] = r.kernelSeconds;
  f["seconds"] = secondsSince(t0);
  return result("EnvResult", f);
}

py::array rotateProduct(const py::object& coeffs, const py::object& euler, const py::object& quat,
                        const std::string& method) {
  if (euler.is_none() == quat.is_none()) throw UsageError("rotate", "give exactly one of euler_zyz and quat");
  if (method != "exact" && method != "projection") throw UsageError("method", "must be exact or projection");
  Rotation r;
  if (!euler.is_none()) {
    const auto a = euler.cast<std::vector<double>>();
    if (a.size() != 3) throw UsageError("euler_zyz", "must be three angles in degrees");
    r = rotationFromEulerZYZ(a[0], a[1], a[2]);
  } else {
    const auto q = quat.cast<std::vector<double>>();
    if (q.size() != 4) throw UsageError("quat", "must be four numbers w, x, y, z");
    r = rotationFromQuaternion(q[0], q[1], q[2], q[3]);
  }
  const ShCoeffs in = shFromArray(coeffs);
  const ShRotationBlocks m = method == "exact" ? shRotationExact(r, in.order) : shRotationProjection(r, in.order);
  return shArray(applyShRotation(in, m));
}

py::object transportProduct(const py::object& meshObj, const py::kwargs& kw) {
  const json p = paramsOf("transport", kw, {{"npy", "-"}}, {"device", "progress"});
  const TransportOptions o = jobs::transportOptionsFrom(p);
  const std::shared_ptr<const Mesh> mesh = meshArg(meshObj, meshAlbedo(o));
  const std::string spec = deviceOf(kw);
  TransportResult r;
  ProgressScope scope(pythonHook(progressOf(kw)));
  {
    py::gil_scoped_release nogil;
    Device d = device(spec);
    r = computeTransport(d.rt, *mesh, o);
  }
  const py::ssize_t nv = py::ssize_t(r.vertexCount), nc = py::ssize_t(r.order) * r.order;
  py::dict f;
  f["coeffs"] = r.channels == 1 ? adopt(std::move(r.coeffs), {nv, nc}) : adopt(std::move(r.coeffs), {nv, 3, nc});
  f["standard_error"] = adopt(std::move(r.stdError), {py::ssize_t(r.stdError.size())});
  f["order"] = r.order;
  f["channels"] = r.channels;
  f["samples"] = r.samples;
  f["rays"] = r.rays;
  f["bounces_used"] = r.bouncesUsed;
  f["standard_error_max"] = r.maxStdError;
  f["standard_error_mean"] = r.meanStdError;
  f["vertices_unoccludable"] = r.verticesUnoccludable;
  f["samples_total"] = r.totalSamples;
  f["seconds"] = r.totalSeconds;
  f["device"] = r.device;
  return result("TransportResult", f);
}

// env of probes and lightmap: the key's path (an SH JSON or a map, read on the device later: the
// parameters of `type` keep it), or radiance coefficients as an (n², 3) array or an EnvResult (read
// here, *fromArray set). Returns the product's parameters (outputs: the kinds its rules need).
json envParams(const char* type, const py::kwargs& kw, const json& outputs, ShCoeffs* env, bool* fromArray) {
  *fromArray = kw.contains("env") && !kw["env"].is_none() && !py::isinstance<py::str>(kw["env"]) &&
               !py::hasattr(kw["env"], "__fspath__");
  std::vector<std::string> own = {"device", "progress"};
  if (*fromArray) {
    own.push_back("env");
    const py::object e = kw["env"];
    *env = shFromArray(py::hasattr(e, "coeffs") ? py::object(e.attr("coeffs")) : e);
  }
  return paramsOf(type, kw, outputs, own);
}

py::object lightmapProduct(const py::object& meshObj, const py::kwargs& kw) {
  ShCoeffs env;
  bool envArray = false;
  const json p = envParams("lightmap", kw, {{"json", "-"}}, &env, &envArray);
  const LightmapOptions o = jobs::lightmapOptionsFrom(p);
  const std::shared_ptr<const Mesh> mesh = meshArg(meshObj, meshAlbedo(o));
  const std::string spec = deviceOf(kw);
  LightmapResult r;
  ProgressScope scope(pythonHook(progressOf(kw)));
  {
    py::gil_scoped_release nogil;
    Device d = device(spec);
    if (!envArray) env = jobs::probeEnvironment(p, [&]() -> Runtime& { return d.rt; }, nullptr);
    r = computeLightmap(d.rt, *mesh, env, o);
  }
  const py::ssize_t h = r.height, w = r.width, nc = py::ssize_t(r.order) * r.order;
  py::dict f;
  f["ao"] = r.ao.empty() ? py::object(py::none()) : py::object(adopt(std::move(r.ao), {h, w}));
  f["bent"] = r.bent.empty() ? py::object(py::none()) : py::object(adopt(std::move(r.bent), {h, w, 3}));
  f["bent_tangent"] = r.bentTangent.empty() ? py::object(py::none()) : py::object(adopt(std::move(r.bentTangent), {h, w, 3}));
  f["irradiance"] = r.irradiance.empty() ? py::object(py::none()) : py::object(adopt(std::move(r.irradiance), {h, w, 3}));
  f["transport"] = r.transport.empty() ? py::object(py::none())
                   : r.transportChannels == 1 ? py::object(adopt(std::move(r.transport), {h, w, nc}))
                                              : py::object(adopt(std::move(r.transport), {h, w, 3, nc}));
  const py::ssize_t ns = py::ssize_t(r.shOrder) * r.shOrder;
  f["sh"] = r.sh.empty() ? py::object(py::none()) : py::object(adopt(std::move(r.sh), {h, w, ns, 3}));
  f["sh_order"] = r.shOrder;
  f["state"] = adopt(std::move(r.state), {h, w});
  f["uv_set"] = r.uvSet;
  f["order"] = r.order;
  f["baked"] = r.baked;
  f["moved"] = r.moved;
  f["buried"] = r.buried;
  f["dilated"] = r.dilated;
  f["charts"] = r.charts;
  f["seam_edges"] = r.seamEdges;
  f["samples"] = r.samples;
  f["rays"] = r.rays;
  f["seconds"] = r.totalSeconds;
  f["device"] = r.device;
  return result("LightmapResult", f);
}

py::object probesProduct(const py::object& meshObj, const py::kwargs& kw) {
  ShCoeffs env;
  bool envArray = false;
  const json p = envParams("probes", kw, {{"npy", "-"}}, &env, &envArray);
  const ProbeOptions o = jobs::probeOptionsFrom(p);
  const std::shared_ptr<const Mesh> mesh = meshArg(meshObj, meshAlbedo(o));
  const std::string spec = deviceOf(kw);
  ProbeGridResult r;
  ProgressScope scope(pythonHook(progressOf(kw)));
  {
    py::gil_scoped_release nogil;
    Device d = device(spec);
    if (!envArray) env = jobs::probeEnvironment(p, [&]() -> Runtime& { return d.rt; }, nullptr);
    r = computeProbeGrid(d.rt, *mesh, env, o);
  }
  const auto& res = r.layout.resolution;
  const py::ssize_t nz = res[2], ny = res[1], nx = res[0], nc = py::ssize_t(r.order) * r.order;
  py::dict f;
  f["coeffs"] = adopt(std::move(r.coeffs), {nz, ny, nx, nc, 3});
  f["positions"] = adopt(std::move(r.positions), {nz, ny, nx, 3});
  f["state"] = adopt(std::move(r.state), {nz, ny, nx});
  f["backface_fraction"] = adopt(std::move(r.backfaceFraction), {nz, ny, nx});
  f["resolution"] = py::make_tuple(nx, ny, nz);
  f["bounds_min"] = py::make_tuple(r.layout.boundsMin[0], r.layout.boundsMin[1], r.layout.boundsMin[2]);
  f["bounds_max"] = py::make_tuple(r.layout.boundsMax[0], r.layout.boundsMax[1], r.layout.boundsMax[2]);
  f["order"] = r.order;
  f["moved"] = r.moved;
  f["invalid"] = r.invalid;
  f["samples"] = r.samples;
  f["rays"] = r.rays;
  f["seconds"] = r.totalSeconds;
  f["device"] = r.device;
  return result("ProbeGridResult", f);
}

py::object glossyProduct(const py::object& meshObj, const py::kwargs& kw) {
  const bool cpca = (kw.contains("cpca_clusters") && !kw["cpca_clusters"].is_none()) ||
                    (kw.contains("cpca_error") && !kw["cpca_error"].is_none());
  json outputs = {{"npy", "-"}};
  if (cpca) outputs["cpca"] = "-";
  const json p = paramsOf("glossy", kw, outputs, {"device", "progress"});
  const GlossyOptions o = jobs::glossyOptionsFrom(p);
  const MatrixDtype dtype = parseMatrixDtype(p["dtype"].get<std::string>());
  const CpcaOptions co = jobs::cpcaOptionsFrom(p);
  const bool brdf = p["brdf"] != "none";
  checkGlossyOptions(o);
  const std::shared_ptr<const Mesh> mesh = meshArg(meshObj, meshAlbedo(o));
  const std::string spec = deviceOf(kw);
  GlossyResult r;
  CpcaResult c;
  const int channels = glossyChannels(*mesh, o);
  ProgressScope scope(pythonHook(progressOf(kw)));
  {
    py::gil_scoped_release nogil;
    Device d = device(spec);
    r = computeGlossyTransfer(d.rt, *mesh, o);
    if (brdf)
      exitRadianceBlock(*mesh, 0, mesh->vertexCount(), channels, o.orderOut, o.orderIn,
                        jobs::brdfFrom(p, o.orderOut), r.matrices.data());
    if (cpca) c = cpcaCompress(r.matrices.data(), mesh->vertexCount(), r.stats.valuesPerVertex(), co);
  }
  std::vector<py::ssize_t> shape = {py::ssize_t(r.stats.vertexCount)};
  if (channels == 3) shape.push_back(3);
  shape.insert(shape.end(), {py::ssize_t(o.orderOut) * o.orderOut, py::ssize_t(o.orderIn) * o.orderIn});
  py::dict f;
  if (dtype == MatrixDtype::Float16) {
    std::vector<uint16_t> h(r.matrices.size());
    for (size_t i = 0; i < h.size(); ++i) h[i] = floatToHalf(r.matrices[i]);
    f["matrices"] = adopt(std::move(h), shape).view("float16");
  } else {
    f["matrices"] = adopt(std::move(r.matrices), shape);
  }
  f["order_out"] = o.orderOut;
  f["order_in"] = o.orderIn;
  f["channels"] = channels;
  f["samples"] = r.stats.samples;
  f["rays"] = r.stats.rays;
  f["standard_error_max"] = r.stats.maxStdError;
  f["standard_error_mean"] = r.stats.meanStdError;
  f["bounces_used"] = r.stats.bouncesUsed;
  f["seconds"] = r.stats.totalSeconds;
  if (cpca) {
    const py::ssize_t k = c.clusters, pv = c.vectors, dim = py::ssize_t(c.dim), v = py::ssize_t(c.vertexCount);
    py::dict d;
    d["clusters"] = c.clusters;
    d["vectors"] = c.vectors;
    d["means"] = adopt(std::move(c.means), {k, dim});
    d["basis"] = adopt(std::move(c.basis), {k, pv, dim});
    d["cluster_of"] = adopt(std::move(c.clusterOf), {v});
    d["weights"] = adopt(std::move(c.weights), {v, pv});
    d["weight_bits"] = c.weightBits;
    d["weight_scales"] = adopt(std::move(c.weightScales), {py::ssize_t(c.weightScales.size())});
    d["vertex_scales"] = adopt(std::move(c.vertexScales), {py::ssize_t(c.vertexScales.size())});
    d["vertex_error"] = adopt(std::move(c.vertexError), {v});
    d["total_error"] = c.totalError;
    f["cpca"] = d;
  } else {
    f["cpca"] = py::none();
  }
  return result("GlossyResult", f);
}

py::object lutProduct(const py::kwargs& kw) {
  const json p = paramsOf("lut", kw, {{"exr", "-"}}, {"device", "progress"});
  const LutOptions o = jobs::lutOptionsFrom(p);
  const std::string spec = deviceOf(kw);
  LutResult r;
  ProgressScope scope(pythonHook(progressOf(kw)));
  {
    py::gil_scoped_release nogil;
    Device d = device(spec);
    r = computeLut(d.rt, o);
  }
  const py::ssize_t n = r.size;
  py::dict f;
  f["a"] = adopt(std::move(r.a), {n, n});
  f["b"] = adopt(std::move(r.b), {n, n});
  f["third"] = r.third.empty() ? py::object(py::none()) : adopt(std::move(r.third), {n, n});
  f["e"] = r.e.empty() ? py::object(py::none()) : adopt(std::move(r.e), {n, n});
  f["e_avg"] = r.eAvg.empty() ? py::object(py::none()) : adopt(std::move(r.eAvg), {n});
  f["size"] = r.size;
  f["samples_total"] = r.totalSamples;
  f["standard_error_max"] = r.stdErrMax;
  f["standard_error_mean"] = r.stdErrMean;
  f["seconds"] = r.totalSeconds;
  f["device"] = r.device;
  return result("LutResult", f);
}

// The chain of prefilter's keywords (`own`: the caller's other keywords).
PrefilterResult prefilterChain(const py::object& source, const py::kwargs& kw, std::vector<std::string> own) {
  own.insert(own.end(), {"device", "progress"});
  const json p = paramsOf("prefilter", kw, {{"ktx2", "-"}}, own);
  const PrefilterOptions o = jobs::prefilterOptionsFrom(p);
  validatePrefilterOptions(o);
  py::object keep;
  EnvMap env = envArg(source, p, false, &keep);
  env.ownTexels();  // the prefilter reads rgb itself
  const std::string spec = deviceOf(kw);
  ProgressScope scope(pythonHook(progressOf(kw)));
  py::gil_scoped_release nogil;
  Device d = device(spec);
  return prefilterEnvironment(d.rt, env, o);
}

py::object prefilterProduct(const py::object& source, const py::kwargs& kw) {
  PrefilterResult r = prefilterChain(source, kw, {});
  py::list levels, roughness, alpha, error;
  for (PrefilterLevel& l : r.levels) {
    const py::ssize_t n = l.spec.size;
    roughness.append(l.spec.roughness);
    alpha.append(l.alphaUsed);
    error.append(py::dict(py::arg("mean") = l.error.mean, py::arg("p99") = l.error.p99, py::arg("max") = l.error.max));
    levels.append(adopt(std::move(l.rgb), {6, n, n, 3}));
  }
  py::dict f;
  f["levels"] = levels;
  f["roughness"] = roughness;
  f["alpha"] = alpha;
  f["error"] = error;
  f["seconds"] = r.totalSeconds;
  f["device"] = r.device;
  return result("PrefilterResult", f);
}

// The path an output is written to ("": None), refused before any work when it would overwrite
// or delete one of `inputs` that is a path, as the command line refuses it.
std::string outputPath(const py::object& out, const char* key, const std::vector<py::object>& inputs) {
  if (out.is_none()) return "";
  if (!isPath(out)) throw UsageError(key, "must be a path");
  std::vector<std::string> in;
  for (const auto& i : inputs)
    if (isPath(i)) in.push_back(pathOf(i));
  const std::string path = pathOf(out);
  jobs::checkOutputsSpareInputs(in, {path});
  return path;
}

py::object iblProduct(const py::object& source, const py::object& dir, const py::kwargs& kw) {
  const json p = paramsOf("ibl", kw, {{"dir", "-"}}, {"device", "progress"});
  const IblPackageOptions o = jobs::iblOptionsFrom(p);
  const std::string out = outputPath(dir, "out_dir", {source});
  py::object keep;
  EnvMap env = envArg(source, p, false, &keep);
  env.ownTexels();  // the packages' prefilter reads rgb itself
  const std::string spec = deviceOf(kw);
  IblPackageResult r;
  ProgressScope scope(pythonHook(progressOf(kw)));
  {
    py::gil_scoped_release nogil;
    Device d = device(spec);
    r = writeIblPackage(d.rt, env, out, o, json({{"parameters", p}}).dump());
  }
  py::list files;
  for (const auto& f : r.files) files.append(f.path);
  py::dict f;
  f["files"] = files;
  f["radiance"] = shArray(r.radiance);
  f["seconds"] = r.seconds;
  return result("IblResult", f);
}

// A path or a sequence of paths (the roots of run), or none.
std::vector<std::string> pathList(const py::object& o) {
  std::vector<std::string> paths;
  if (o.is_none()) return paths;
  if (isPath(o)) return {pathOf(o)};
  for (const py::handle& p : o.cast<py::sequence>()) paths.push_back(pathOf(p));
  return paths;
}

py::object runJobs(const py::object& files, bool force, bool dryRun, const py::object& only, const py::object& shard,
                   const std::string& deviceSpec, bool quiet, const py::object& progress, const py::object& inputRoots,
                   const py::object& outputRoots) {
  if (!progress.is_none() && !PyCallable_Check(progress.ptr()))
    throw UsageError("progress", "must be a callable progress(stage, fraction) or None");
  std::vector<jobs::JobFileRef> refs;
  if (isPath(files)) {
    refs.push_back({pathOf(files), "", ""});
  } else {
    for (const py::handle& f : files.cast<py::sequence>()) refs.push_back({pathOf(f), "", ""});
  }
  jobs::RunOptions options;
  options.force = force;
  options.dryRun = dryRun;
  options.device = deviceSpec;
  if (!only.is_none())
    for (const py::handle& id : only.cast<py::sequence>()) options.only.insert(id.cast<std::string>());
  if (!shard.is_none()) options.shard = jobs::parseShardSpec(shard.cast<std::string>(), "shard");
  if (!inputRoots.is_none() || !outputRoots.is_none())
    options.confinement = std::make_shared<jobs::Confinement>(pathList(inputRoots), pathList(outputRoots));
  jobs::RunTotals t;
  ProgressScope scope(pythonHook(progress.is_none() ? nullptr : progress.ptr()));
  {
    py::gil_scoped_release nogil;
    std::unique_ptr<Device> d;
    if (!dryRun) d = std::make_unique<Device>(device(deviceSpec));  // the runner's runtime is the same one
    jobs::Reporter reporter(quiet, false);
    jobs::Runner runner(options, reporter);
    t = runner.run(refs);
  }
  py::dict f;
  f["ok"] = t.ok;
  f["skipped"] = t.skipped;
  f["failed"] = t.failed;
  f["bad_files"] = t.badFiles;
  f["seconds"] = t.seconds;
  return result("RunResult", f);
}

// --- previews: linear images as (H, W, 3) float32 arrays, and the PNG the command writes ---

py::array imageArray(LinearImage&& img) {
  const py::ssize_t h = img.height, w = img.width;
  return adopt(std::move(img.rgb), {h, w, 3});
}

void writePng(const std::string& path, const LinearImage& img, double exposure, const std::string& what) {
  if (path.empty()) return;
  py::gil_scoped_release nogil;
  writePreviewPng(path, img, ToneMap{exposure}, {{"Description", what}});
}

// Radiance coefficients: an (n², 3) array, or a result whose `radiance` (env, ibl) holds them.
ShCoeffs radianceArg(const py::object& v) {
  return shFromArray(py::hasattr(v, "radiance") ? py::object(v.attr("radiance")) : v);
}

py::array previewEnv(const py::object& source, const py::kwargs& kw) {
  const int width = kw.contains("size") ? kw["size"].cast<int>() : 512;
  const double exposure = kw.contains("exposure") ? kw["exposure"].cast<double>() : 0.0;
  if (width < 16 || width > 8192) throw UsageError("size", "must be 16..8192 (the panel width)");
  const bool coefficients = py::isinstance<py::array>(source) && py::array(source).ndim() == 2;
  const std::string out = outputPath(kw.contains("out") ? py::object(kw["out"]) : py::none(), "out", {source});
  ShCoeffs radiance;
  EnvMap env;
  py::object keep;  // an array the map reads in place
  if (coefficients || py::hasattr(source, "radiance")) {
    radiance = radianceArg(source);
  } else {
    const json p = paramsOf("env", kw, {{"json", "-"}}, {"device", "progress", "size", "exposure", "out"});
    if (p["order"] == "auto") throw UsageError("order", "a preview needs an order (1..32)");
    const EnvProjectOptions po = jobs::envProjectOptionsFrom(p);
    env = envArg(source, p, true, &keep);
    const std::string spec = deviceOf(kw);
    py::gil_scoped_release nogil;
    Device d = device(spec);
    const EnvProjectResult r = projectEnvironment(d.rt, env, po);
    radiance = applyWindowAndQuantity(r.radiance, r.windowWeights, ShQuantity::Radiance);
  }
  LinearImage img;
  {
    py::gil_scoped_release nogil;
    img = renderEnvPreview(env.width > 0 ? &env : nullptr, radiance, width);
  }
  writePng(out, img, exposure, "prtbake environment preview: environment | SH radiance reconstruction | irradiance/pi");
  return imageArray(std::move(img));
}

// The mesh previews' image size and camera: (width, height), and front, side, top or (yaw, pitch).
MeshPreviewOptions previewView(std::pair<int, int> size, const py::object& view) {
  MeshPreviewOptions o;
  o.width = size.first, o.height = size.second;
  if (o.width < 16 || o.height < 16 || o.width > 8192 || o.height > 8192)
    throw UsageError("size", "must be (width, height), each 16..8192");
  if (py::isinstance<py::str>(view)) {
    const std::string v = view.cast<std::string>();
    if (v == "side") o.yawDeg = 90;
    else if (v == "top") o.pitchDeg = 90;
    else if (v != "front") throw UsageError("view", "must be front, side, top or (yaw, pitch) in degrees");
  } else {
    const auto yp = view.cast<std::pair<double, double>>();
    o.yawDeg = yp.first, o.pitchDeg = yp.second;
  }
  return o;
}

py::array previewMesh(const py::object& meshObj, const py::object& transport, const py::object& radiance,
                      std::pair<int, int> size, const py::object& view, double rotateLight, double exposure,
                      const py::object& outObj, const std::string& spec) {
  const std::string out = outputPath(outObj, "out", {meshObj});
  const std::shared_ptr<const Mesh> mesh = meshArg(meshObj, MeshAlbedo::Textures);
  MeshPreviewOptions o = previewView(size, view);
  o.lightRotationDeg = rotateLight;
  const FloatArray t = FloatArray::ensure(py::hasattr(transport, "coeffs") ? py::object(transport.attr("coeffs"))
                                                                          : transport);
  TransportCoeffs tc;
  if (!t || (t.ndim() != 2 && !(t.ndim() == 3 && t.shape(1) == 3)))
    throw UsageError("transport", "must be a (V, n²) or (V, 3, n²) array, or a TransportResult");
  const py::ssize_t nc = t.shape(t.ndim() - 1);
  while (tc.order * tc.order < nc) ++tc.order;
  if (tc.order * tc.order != nc) throw UsageError("transport", "the last axis must hold n² coefficients");
  tc.channels = t.ndim() == 3 ? 3 : 1;
  tc.vertexCount = size_t(t.shape(0));
  tc.coeffs.assign(t.data(), t.data() + t.size());
  const ShCoeffs l = radianceArg(radiance);
  LinearImage img;
  {
    py::gil_scoped_release nogil;
    Device d = device(spec);
    img = renderMeshPreview(d.rt, *mesh, tc, l, o).image;
  }
  writePng(out, img, exposure, "prtbake mesh preview: the mesh shaded with its transport under the SH radiance");
  return imageArray(std::move(img));
}

// A lightmap to preview: the directory prtbake lightmap wrote (readLightmap), or a LightmapResult
// (its arrays copied once into the library's layout).
LightmapResult lightmapArg(const py::object& v) {
  if (isPath(v)) {
    const std::string dir = pathOf(v);
    py::gil_scoped_release nogil;
    return readLightmap(dir);
  }
  if (!py::hasattr(v, "state") || !py::hasattr(v, "uv_set"))
    throw UsageError("lightmap", "must be a LightmapResult or the directory prtbake lightmap wrote");
  using ByteArray = py::array_t<uint8_t, py::array::c_style | py::array::forcecast>;
  const ByteArray state = ByteArray::ensure(v.attr("state"));
  if (!state || state.ndim() != 2) throw UsageError("lightmap", "state must be an (H, W) array");
  LightmapResult lm;
  lm.height = int(state.shape(0)), lm.width = int(state.shape(1));
  lm.state.assign(state.data(), state.data() + state.size());
  lm.uvSet = v.attr("uv_set").cast<int>();
  auto plane = [&](const char* name, LightmapProduct p, std::vector<float>& dst, int ndim) -> FloatArray {
    if (!py::hasattr(v, name) || v.attr(name).is_none()) return FloatArray();
    FloatArray a = FloatArray::ensure(v.attr(name));
    if (!a || (a.ndim() != ndim && !(p == kLightmapTransport && a.ndim() == 4)) || a.shape(0) != lm.height ||
        a.shape(1) != lm.width)
      throw UsageError("lightmap", std::string(name) + " must be an array of the state's (H, W) size");
    dst.assign(a.data(), a.data() + a.size());
    lm.products |= p;
    return a;
  };
  plane("ao", kLightmapAo, lm.ao, 2);
  plane("bent", kLightmapBent, lm.bent, 3);
  plane("bent_tangent", kLightmapBentTangent, lm.bentTangent, 3);
  plane("irradiance", kLightmapIrradiance, lm.irradiance, 3);
  if (plane("sh", kLightmapSh, lm.sh, 4)) lm.shOrder = v.attr("sh_order").cast<int>();
  if (const FloatArray t = plane("transport", kLightmapTransport, lm.transport, 3)) {
    const py::ssize_t nc = t.shape(t.ndim() - 1);
    while (py::ssize_t(lm.order) * lm.order < nc) ++lm.order;
    lm.transportChannels = t.ndim() == 4 ? 3 : 1;
  }
  return lm;
}

// Each product of a lightmap on the mesh and as the atlas (prtbake preview lightmap).
py::array previewLightmap(const py::object& meshObj, const py::object& lightmap, std::pair<int, int> size,
                          const py::object& view, double exposure, const py::object& outObj, const std::string& spec) {
  const std::string out = outputPath(outObj, "out", {meshObj, lightmap});
  const std::shared_ptr<const Mesh> mesh = meshArg(meshObj, MeshAlbedo::Textures);
  MeshPreviewOptions o = previewView(size, view);
  const LightmapResult lm = lightmapArg(lightmap);
  LinearImage img;
  {
    py::gil_scoped_release nogil;
    Device d = device(spec);
    img = renderLightmapPreview(d.rt, *mesh, lm, o);
  }
  writePng(out, img, exposure, "prtbake lightmap preview: each product on the mesh and as the atlas");
  return imageArray(std::move(img));
}

// Every level of the chain as a lat-long panel and the split-sum spheres (prtbake preview prefilter).
py::array previewPrefilter(const py::object& source, const py::kwargs& kw) {
  const int width = kw.contains("panel_width") ? kw["panel_width"].cast<int>() : 256;
  if (width < 16 || width > 8192) throw UsageError("panel_width", "must be 16..8192");
  const std::string out = outputPath(kw.contains("out") ? py::object(kw["out"]) : py::none(), "out", {source});
  const PrefilterResult r = prefilterChain(source, kw, {"panel_width", "out"});
  LinearImage img;
  {
    py::gil_scoped_release nogil;
    Device d = device(deviceOf(kw));
    img = renderPrefilterPreview(d.rt, r, width);
  }
  writePng(out, img, 0.0, "prtbake prefilter preview: each level as a lat-long panel, and split-sum spheres r = 0 ... 1");
  return imageArray(std::move(img));
}

py::array previewLut(const py::object& lut, int size, const py::object& outObj) {
  const std::string out = outputPath(outObj, "out", {});
  const FloatArray a = FloatArray::ensure(lut.attr("a")), b = FloatArray::ensure(lut.attr("b"));
  if (!a || !b || a.ndim() != 2 || a.shape(0) != a.shape(1) || b.ndim() != 2 || b.shape(0) != a.shape(0) ||
      b.shape(1) != a.shape(1))
    throw UsageError("lut", "must be a LutResult (square a and b tables)");
  std::vector<LutChannel> channels = {{"R = A (scale)", a.data()}, {"G = B (bias)", b.data()}};
  FloatArray third;
  if (py::hasattr(lut, "third") && !lut.attr("third").is_none()) {
    third = FloatArray::ensure(lut.attr("third"));
    if (third && third.size() == a.size()) channels.push_back({"B = third table", third.data()});
  }
  LinearImage img = renderLutPreview(int(a.shape(0)), channels, "N.V", "rough", 0.0f, 1.0f, size);
  writePng(out, img, 0.0, "prtbake LUT preview: x = N.V (0..1), y = roughness (0..1, bottom to top)");
  return imageArray(std::move(img));
}

py::dict readExrFile(const py::object& file) {
  if (!isPath(file)) throw UsageError("path", "must be a path");
  const std::string path = pathOf(file);
  ExrImage img;
  {
    py::gil_scoped_release nogil;
    img = readExr(path);
  }
  py::dict out;
  for (size_t i = 0; i < img.channelNames.size(); ++i)
    out[py::str(img.channelNames[i])] = adopt(std::move(img.channels[i]), {img.height, img.width});
  return out;
}

py::list devices() {
  py::list out;
  for (const DeviceInfo& d : listDevices())
    out.append(py::dict(py::arg("index") = d.index, py::arg("platform") = d.platform, py::arg("name") = d.name,
                        py::arg("type") = d.type, py::arg("compute_units") = d.computeUnits,
                        py::arg("global_memory_bytes") = d.globalMemBytes));
  return out;
}

// A view of one of the mesh's vectors as an (N, 3) array that keeps the mesh alive.
template <class T>
py::array meshView(const py::object& self, const std::vector<T>& v) {
  return py::array_t<T>({py::ssize_t(v.size() / 3), py::ssize_t(3)}, v.data(), self);
}

}  // namespace
}  // namespace prtbake::python

using namespace prtbake;
using namespace prtbake::python;

PYBIND11_MODULE(_prtbake, m) {
  m.doc() = "prtbake's library: SH lighting, PRT transport, BRDF tables and prefiltered environments on OpenCL";
  // The library's errors: bad parameters are ValueError; the others are prtbake's own.
  static py::exception<Error> error(m, "Error", PyExc_RuntimeError);
  static py::exception<InputError> inputError(m, "InputError", error.ptr());
  static py::exception<DeviceError> deviceError(m, "DeviceError", error.ptr());
  static py::exception<OutputError> outputError(m, "OutputError", error.ptr());
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const Cancelled& e) {
      // Stopped by Ctrl-C or by the progress function: its exception is already set.
      if (!PyErr_Occurred()) PyErr_SetString(PyExc_KeyboardInterrupt, e.what());
    } catch (const UsageError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const InputError& e) {
      inputError(e.what());
    } catch (const DeviceError& e) {
      deviceError(e.what());
    } catch (const OutputError& e) {
      outputError(e.what());
    } catch (const Error& e) {
      error(e.what());
    } catch (const cl::Error& e) {
      deviceError((std::string("OpenCL: ") + e.what() + " (" + std::to_string(e.err()) + ")").c_str());
    }
  });

  py::class_<Mesh, std::shared_ptr<Mesh>>(m, "Mesh")
      .def(py::init(&meshFromArrays), py::arg("positions"), py::arg("indices"), py::arg("normals") = py::none(),
           py::arg("albedo") = py::none(), py::arg("uvs") = py::none(), py::arg("tangents") = py::none())
      .def_static(
          "load", [](const py::object& file) {
            if (!isPath(file)) throw UsageError("path", "must be a path");
            const std::string path = pathOf(file);
            py::gil_scoped_release nogil;
            return std::make_shared<Mesh>(loadMesh(path, MeshAlbedo::Textures));
          },
          py::arg("path"))
      .def_property_readonly("positions", [](py::object self) { return meshView(self, self.cast<Mesh&>().positions); })
      .def_property_readonly("normals", [](py::object self) { return meshView(self, self.cast<Mesh&>().normals); })
      .def_property_readonly("albedo", [](py::object self) { return meshView(self, self.cast<Mesh&>().albedo); })
      .def_property_readonly("indices", [](py::object self) { return meshView(self, self.cast<Mesh&>().indices); })
      .def_property_readonly("uv_sets", [](const Mesh& mesh) {
        py::list sets;
        for (size_t k = 0; k < mesh.uvs.size(); ++k)
          if (!mesh.uvs[k].empty()) sets.append(k);
        return sets;
      })
      .def_property_readonly("vertex_count", &Mesh::vertexCount)
      .def_property_readonly("triangle_count", &Mesh::triangleCount)
      .def_property_readonly("source", [](const Mesh& mesh) { return mesh.sourcePath; })
      .def("__repr__", [](const Mesh& mesh) {
        return "<prtbake.Mesh: " + std::to_string(mesh.vertexCount()) + " vertices, " +
               std::to_string(mesh.triangleCount()) + " triangles" +
               (mesh.sourcePath.empty() ? std::string() : ", from " + mesh.sourcePath) + ">";
      });

  m.def("devices", &devices);
  m.def("env", &envProduct, py::arg("source"));
  m.def("rotate", &rotateProduct, py::arg("coeffs"), py::kw_only(), py::arg("euler_zyz") = py::none(),
        py::arg("quat") = py::none(), py::arg("method") = "exact");
  m.def("transport", &transportProduct, py::arg("mesh"));
  m.def("glossy", &glossyProduct, py::arg("mesh"));
  m.def("probes", &probesProduct, py::arg("scene"));
  m.def("lightmap", &lightmapProduct, py::arg("mesh"));
  m.def("lut", &lutProduct);
  m.def("prefilter", &prefilterProduct, py::arg("source"));
  m.def("ibl", &iblProduct, py::arg("source"), py::arg("out_dir"));
  m.def("run", &runJobs, py::arg("job_files"), py::kw_only(), py::arg("force") = false, py::arg("dry_run") = false,
        py::arg("only") = py::none(), py::arg("shard") = py::none(), py::arg("device") = "", py::arg("quiet") = true,
        py::arg("progress") = py::none(), py::arg("input_root") = py::none(), py::arg("output_root") = py::none());
  m.def("read_exr", &readExrFile, py::arg("path"));
  m.def("preview_env", &previewEnv, py::arg("source"));
  m.def("preview_mesh", &previewMesh, py::arg("mesh"), py::arg("transport"), py::arg("radiance"), py::kw_only(),
        py::arg("size") = std::pair<int, int>(800, 600), py::arg("view") = "front", py::arg("rotate_light") = 0.0,
        py::arg("exposure") = 0.0, py::arg("out") = py::none(), py::arg("device") = "");
  m.def("preview_lightmap", &previewLightmap, py::arg("mesh"), py::arg("lightmap"), py::kw_only(),
        py::arg("size") = std::pair<int, int>(800, 600), py::arg("view") = "front", py::arg("exposure") = 0.0,
        py::arg("out") = py::none(), py::arg("device") = "");
  m.def("preview_prefilter", &previewPrefilter, py::arg("source"));
  m.def("preview_lut", &previewLut, py::arg("lut"), py::kw_only(), py::arg("size") = 256, py::arg("out") = py::none());
  // Each product's keywords as the one declaration gives them: {product: [(key, kind, default, values, help)]},
  // kind one of integer, integer_or_auto, number, boolean, choice, choice_list, path, number_list.
  m.def("keywords", []() {
    auto kindName = [](const jobs::KeySpec& k) -> const char* {
      switch (k.kind) {
        case jobs::ValueKind::Integer: return k.orAuto ? "integer_or_auto" : "integer";
        case jobs::ValueKind::Number: return "number";
        case jobs::ValueKind::Boolean: return "boolean";
        case jobs::ValueKind::Choice: return "choice";
        case jobs::ValueKind::ChoiceList: return "choice_list";
        case jobs::ValueKind::Path: return "path";
        case jobs::ValueKind::NumberList: return "number_list";
      }
      return "";
    };
    py::dict out;
    for (const char* name : {"env", "transport", "glossy", "lut", "prefilter", "ibl", "probes", "lightmap"}) {
      const jobs::JobType* t = jobs::findJobType(name);
      py::list keys;
      for (const auto& k : t->keys)
        if (k.onCommandLine)
          keys.append(py::make_tuple(k.name, kindName(k), fromJson(k.defaultValue), jobs::describeRange(k), k.help));
      out[name] = keys;
    }
    return out;
  });
  m.attr("__version__") = PRTBAKE_VERSION;
}
