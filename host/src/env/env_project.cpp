// Environment → SH: the OpenCL projection and its double-precision reference.
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>

#include "core/constants.h"
#include "core/kernel_options.h"
#include "prtbake/clock.h"
#include "prtbake/env.h"
#include "prtbake/progress.h"
#include "prtbake/error.h"
#include "prtbake/sh.h"

namespace prtbake {
namespace {

void checkOrder(int order) {
  if (order < 1 || order > kMaxShOrder)
    throw UsageError("--order", std::to_string(order) + " is out of range [1, " + std::to_string(kMaxShOrder) + "]");
}

// Vector width of the row loop: wide vectors while the accumulators fit in
// registers or L1, scalar for high orders (private arrays of 3n² vectors would
// be too large). Measured in bench/bench_env.cpp.
int vectorWidth(const Runtime& rt, int order) {
  if (rt.info().type == "gpu") return 1;  // one row per thread; SIMT lanes come from rows
  if (order <= 4) return 16;
  if (order <= 8) return 8;
  return 1;
}

// Exact solid angles of the rows 0..(n+1)/2−1 of an n×n face (the lower rows
// mirror them), as floats for the kernel. The corner function f(u, v) is
// evaluated once per corner of the upper-left quadrant and texels are the
// differences f(u0,v0) − f(u0,v1) − f(u1,v0) + f(u1,v1) (envmap.h), so a 2048²
// face costs 1M atan2 instead of 8M. Tables are kept per size for later calls.
std::shared_ptr<const RawVector<float>> cubeSolidAngleTable(int n) {
  static std::mutex mutex;
  static std::map<int, std::shared_ptr<const RawVector<float>>> cache;
  std::lock_guard<std::mutex> lock(mutex);
  if (auto it = cache.find(n); it != cache.end()) return it->second;
  const int half = (n + 1) / 2;  // rows (and columns) 0..half−1 cover a quadrant
  // f(u, v) at the texel corners of two consecutive corner rows.
  std::vector<double> top(size_t(half) + 1), bottom(size_t(half) + 1);
  auto cornerRow = [&](int r, std::vector<double>& f) {
    const double v = 2.0 * r / n - 1.0;
    for (int c = 0; c <= half; ++c) {
      const double u = 2.0 * c / n - 1.0;
      f[size_t(c)] = std::atan2(u * v, std::sqrt(u * u + v * v + 1.0));
    }
  };
  auto table = std::make_shared<RawVector<float>>(size_t(half) * size_t(n));
  cornerRow(0, top);
  for (int r = 0; r < half; ++r) {
    cornerRow(r + 1, bottom);
    for (int c = 0; c < half; ++c) {
      const float w = float(top[size_t(c)] - bottom[size_t(c)] - top[size_t(c) + 1] + bottom[size_t(c) + 1]);
      (*table)[size_t(r) * size_t(n) + size_t(c)] = w;
      (*table)[size_t(r) * size_t(n) + size_t(n - 1 - c)] = w;  // Ω is symmetric in u
    }
    top.swap(bottom);
  }
  cache.emplace(n, table);
  return table;
}

// Highest order projected by row moments (the host's polynomial fit per row grows as n³).
constexpr int kMomentsMaxOrder = 8;

// Turns the per-row moments M_la (env_project.cl, project_cube_moments) into SH
// coefficients: for each row, P_lm(u) = r^l Y_lm(h(u)/r) is a polynomial of degree l
// in u; its coefficients come from interpolation at l+1 Chebyshev points (exact for a
// polynomial, computed in double), and L_lm += Σ_a p_lma M_la. Rows are added in order.
void addRowMoments(const EnvMap& env, int order, const std::vector<float>& bases, const std::vector<float>& sums,
                   ShCoeffs& out) {
  const int n = env.width, nc = order * order, nm = order * (order + 1) / 2;
  // Chebyshev points and, per degree l, the inverse Vandermonde matrix on the first l+1 of them.
  std::vector<double> x(static_cast<size_t>(order));
  for (int j = 0; j < order; ++j) x[size_t(j)] = std::cos(kPi * (j + 0.5) / order);
  std::vector<std::vector<double>> vinv(static_cast<size_t>(order));
  for (int l = 0; l < order; ++l) {
    const int m = l + 1;
    std::vector<double> a(size_t(m * m)), inv(size_t(m * m), 0.0);
    for (int j = 0; j < m; ++j)
      for (int k = 0; k < m; ++k) a[size_t(j * m + k)] = std::pow(x[size_t(j)], k);
    for (int i = 0; i < m; ++i) inv[size_t(i * m + i)] = 1.0;
    for (int c = 0; c < m; ++c) {  // Gauss–Jordan with partial pivoting
      int piv = c;
      for (int r = c + 1; r < m; ++r)
        if (std::abs(a[size_t(r * m + c)]) > std::abs(a[size_t(piv * m + c)])) piv = r;
      for (int k = 0; k < m; ++k) std::swap(a[size_t(c * m + k)], a[size_t(piv * m + k)]), std::swap(inv[size_t(c * m + k)], inv[size_t(piv * m + k)]);
      const double p = a[size_t(c * m + c)];
      for (int k = 0; k < m; ++k) a[size_t(c * m + k)] /= p, inv[size_t(c * m + k)] /= p;
      for (int r = 0; r < m; ++r)
        if (r != c) {
          const double f = a[size_t(r * m + c)];
          for (int k = 0; k < m; ++k) a[size_t(r * m + k)] -= f * a[size_t(c * m + k)], inv[size_t(r * m + k)] -= f * inv[size_t(c * m + k)];
        }
    }
    vinv[size_t(l)] = inv;  // coefficient a of the fit = Σ_j inv[a][j] · value(x_j)
  }
  std::vector<double> y(static_cast<size_t>(nc)), values(size_t(order) * size_t(nc)), p(static_cast<size_t>(order));
  for (int face = 0; face < 6; ++face) {
    const float* b = bases.data() + 9 * face;
    for (int row = 0; row < n; ++row) {
      const double v = 2.0 * (row + 0.5) / n - 1.0;
      // Ỹ_lm(h) = |h|^l Y_lm(h/|h|) at h(x_j) = x_j U + v V + N.
      for (int j = 0; j < order; ++j) {
        double h[3];
        for (int k = 0; k < 3; ++k) h[k] = x[size_t(j)] * b[k] + v * b[3 + k] + b[6 + k];
        const double len = std::sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
        shEval(order, h[0] / len, h[1] / len, h[2] / len, y.data());
        double scale = 1.0;
        for (int l = 0; l < order; ++l, scale *= len)
          for (int mm = -l; mm <= l; ++mm) values[size_t(j) * nc + size_t(shIndex(l, mm))] = scale * y[size_t(shIndex(l, mm))];
      }
      const float* mom = sums.data() + (size_t(face) * n + size_t(row)) * 3 * size_t(nm);
      for (int l = 0; l < order; ++l) {
        const int m = l + 1, first = l * (l + 1) / 2;  // moments M_l0..M_ll start at index first
        for (int mm = -l; mm <= l; ++mm) {
          const int i = shIndex(l, mm);
          for (int a = 0; a < m; ++a) {
            double s = 0;
            for (int j = 0; j < m; ++j) s += vinv[size_t(l)][size_t(a * m + j)] * values[size_t(j) * nc + size_t(i)];
            p[size_t(a)] = s;
          }
          for (int ch = 0; ch < 3; ++ch) {
            double acc = 0;
            for (int a = 0; a < m; ++a) acc += p[size_t(a)] * double(mom[size_t(ch * nm + first + a)]);
            out.rgb[size_t(i)][size_t(ch)] += acc;
          }
        }
      }
    }
  }
}

double eventSeconds(const cl::Event& e) {
  const auto t0 = e.getProfilingInfo<CL_PROFILING_COMMAND_START>();
  const auto t1 = e.getProfilingInfo<CL_PROFILING_COMMAND_END>();
  return double(t1 - t0) * 1e-9;
}

}  // namespace

std::string detail::envProjectOptions(int order, int vectorWidth, EnvStorage storage) {
  return "-DSH_ORDER=" + std::to_string(order) + " -DVW=" + std::to_string(vectorWidth) +
         " -DENV_TEXELS=" + std::to_string(int(storage));
}

namespace {

// Cube face bases (u, v, n of each face) rotated by `yaw` radians about +Y.
std::vector<float> rotatedFaceBases(const EnvMap& env, double yaw) {
  std::vector<float> table;
  const double cy = std::cos(yaw), sy = std::sin(yaw);
  for (const auto& f : env.faces)
    for (const auto* a : {&f.axisU, &f.axisV, &f.axisN}) {
      const auto& v = *a;
      table.insert(table.end(), {float(cy * v[0] + sy * v[2]), float(v[1]), float(-sy * v[0] + cy * v[2])});
    }
  return table;
}

// The lat-long kernel's column table: sin λ of every column, then cos λ (λ with the yaw).
std::vector<float> latLongColumns(int w, double yaw) {
  std::vector<float> table(2 * size_t(w));
  for (int c = 0; c < w; ++c) {
    const double lambda = -2.0 * kPi * ((c + 0.5) / w - 0.5) + yaw;
    table[size_t(c)] = float(std::sin(lambda));
    table[size_t(w + c)] = float(std::cos(lambda));
  }
  return table;
}

// The lat-long kernel's row table for rows firstRow..firstRow+h-1 of a map fullHeight rows
// high: sin φ, cos φ and the solid angle of one texel of the row.
std::vector<float> latLongRows(int w, int h, int firstRow, int fullHeight) {
  std::vector<float> table(3 * size_t(h));
  for (int i = 0; i < h; ++i) {
    const int r = firstRow + i;
    const double phi = kPi * (0.5 - (r + 0.5) / fullHeight);
    const double top = kPi * (0.5 - double(r) / fullHeight), bottom = kPi * (0.5 - double(r + 1) / fullHeight);
    table[3 * size_t(i)] = float(std::sin(phi));
    table[3 * size_t(i) + 1] = float(std::cos(phi));
    table[3 * size_t(i) + 2] = float((2.0 * kPi / w) * (std::sin(top) - std::sin(bottom)));
  }
  return table;
}

// Adds the radiance of env's texels to `radiance`, row partial sums in row order. A lat-long
// `env` may hold a band of rows only: rows firstRow.. of a map fullHeight rows high.
void addProjection(Runtime& rt, const EnvMap& env, int firstRow, int fullHeight, const EnvProjectOptions& options,
                   ShCoeffs& radiance, EnvProjectResult& result) {
  const int order = options.order, nc = order * order;
  const int vw = options.vectorWidth ? options.vectorWidth : vectorWidth(rt, order);
  if (vw != 1 && vw != 8 && vw != 16) throw UsageError("vector width", "must be 1, 8 or 16");
  const EnvStorage storage = env.storage();
  const std::string buildOptions = detail::envProjectOptions(order, vw, storage);
  const bool cube = env.layout == EnvLayout::Cube;
  // Cube faces on vector devices go by row moments (fewer accumulators, no basis per
  // texel), with the polynomial coefficients formed on the host; see env_project.cl.
  const bool moments = cube && vw > 1 && order <= kMomentsMaxOrder;
  cl::Kernel kernel = rt.kernel("env_project.cl",
                                moments ? "project_cube_moments" : cube ? "project_cube" : "project_latlong", buildOptions);
  const int perRow = moments ? 3 * order * (order + 1) / 2 : 3 * nc;

  const auto t0 = std::chrono::steady_clock::now();
  const cl_mem_flags hostFlags =
      rt.info().type == "cpu" ? CL_MEM_USE_HOST_PTR : CL_MEM_COPY_HOST_PTR;  // zero copy on CPU devices
  // The texels in their own storage (float, half or 8-bit codes), and the codes' table.
  void* texels = storage == EnvStorage::Code8 ? static_cast<void*>(const_cast<uint8_t*>(env.codes.data()))
                 : storage == EnvStorage::Half ? static_cast<void*>(const_cast<uint16_t*>(env.halfRgb.data()))
                                               : static_cast<void*>(const_cast<float*>(env.floatTexels()));
  const size_t texelBytes = storage == EnvStorage::Code8 ? env.codes.size()
                            : storage == EnvStorage::Half ? 2 * env.halfRgb.size()
                                                          : 4 * 3 * env.texelCount();
  cl::Buffer rgb(rt.context(), CL_MEM_READ_ONLY | hostFlags, texelBytes, texels);
  cl::Buffer codeTable(rt.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, 256 * sizeof(float),
                       const_cast<float*>(env.codeToLinear.data()));
  const size_t rows = cube ? 6 * size_t(env.width) : size_t(env.height);
  cl::Buffer partials(rt.context(), CL_MEM_WRITE_ONLY, rows * size_t(perRow) * sizeof(float));
  const double yaw = env.yawDegrees * kPi / 180.0;
  std::vector<float> table1, table2;
  std::shared_ptr<const RawVector<float>> solidAngles;  // cube: the quadrant's texel solid angles
  cl::Buffer buf1, buf2;
  if (cube) {
    const int n = env.width;
    solidAngles = cubeSolidAngleTable(n);
    table2 = rotatedFaceBases(env, yaw);
    buf1 = cl::Buffer(rt.context(), CL_MEM_READ_ONLY | hostFlags, solidAngles->size() * 4,
                      const_cast<float*>(solidAngles->data()));
    buf2 = cl::Buffer(rt.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, table2.size() * 4, table2.data());
    int arg = 0;
    kernel.setArg(arg++, rgb);
    kernel.setArg(arg++, codeTable);
    kernel.setArg(arg++, buf1);
    if (!moments) kernel.setArg(arg++, buf2);
    kernel.setArg(arg++, n);
    kernel.setArg(arg++, partials);
  } else {
    const int w = env.width, h = env.height;
    table1 = latLongColumns(w, yaw);
    table2 = latLongRows(w, h, firstRow, fullHeight);
    buf1 = cl::Buffer(rt.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, table1.size() * 4, table1.data());
    buf2 = cl::Buffer(rt.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, table2.size() * 4, table2.data());
    kernel.setArg(0, rgb);
    kernel.setArg(1, codeTable);
    kernel.setArg(2, buf1);
    kernel.setArg(3, buf2);
    kernel.setArg(4, w);
    kernel.setArg(5, h);
    kernel.setArg(6, partials);
  }
  result.uploadSeconds += secondsSince(t0);

  // One row per work-item; on CPUs small work-groups (4 rows) keep the split over
  // PoCL's threads even while amortising the per-group launch cost.
  const size_t local = options.rowsPerGroup > 0 ? size_t(options.rowsPerGroup) : rt.info().type == "cpu" ? 4 : 64;
  const size_t global = (rows + local - 1) / local * local;
  cl::Event done;
  rt.queue().enqueueNDRangeKernel(kernel, cl::NullRange, cl::NDRange(global), cl::NDRange(local), nullptr, &done);
  std::vector<float> sums(rows * size_t(perRow));
  rt.queue().enqueueReadBuffer(partials, CL_TRUE, 0, sums.size() * sizeof(float), sums.data());
  result.kernelSeconds += eventSeconds(done);
  result.texels += (long long)env.texelCount();

  if (moments) {
    addRowMoments(env, order, table2, sums, radiance);
  } else {
    for (size_t r = 0; r < rows; ++r) {
      const float* s = sums.data() + r * 3 * size_t(nc);
      for (int ch = 0; ch < 3; ++ch)
        for (int k = 0; k < nc; ++k) radiance.rgb[size_t(k)][size_t(ch)] += double(s[ch * nc + k]);
    }
  }
}

ShCoeffs zeroCoeffs(int order) {
  ShCoeffs c;
  c.order = order;
  c.rgb.assign(size_t(order) * size_t(order), Rgb{0, 0, 0});
  return c;
}

// The radiance checked, windowed and turned into the quantity asked for.
void finishProjection(const ShCoeffs& radiance, const std::string& source, const EnvProjectOptions& options,
                      EnvProjectResult& result) {
  for (const auto& c : radiance.rgb)
    for (double v : c)
      if (!std::isfinite(v)) throw InputError(source, "projection overflowed (radiance too large for float)");
  result.radiance = radiance;
  if (options.window == ShWindow::Auto) {
    result.windowWeights =
        deringingWindow(radiance, &result.autoWindowLambda, &result.minIrradianceBefore, &result.minIrradianceAfter);
  } else {
    result.windowWeights = windowWeights(options.window, options.order);
  }
  result.coeffs = applyWindowAndQuantity(radiance, result.windowWeights, options.quantity);
}

}  // namespace

EnvProjectResult projectEnvironment(Runtime& rt, const EnvMap& env, const EnvProjectOptions& options) {
  checkOrder(options.order);
  if (env.texelCount() == 0) throw InputError(env.source, "empty environment");
  EnvProjectResult result;
  ShCoeffs radiance = zeroCoeffs(options.order);
  addProjection(rt, env, 0, env.height, options, radiance, result);
  finishProjection(radiance, env.source, options, result);
  return result;
}

EnvProjectResult projectEnvironmentFile(const std::function<Runtime&()>& runtime, const std::string& path,
                                        const EnvLoadOptions& loadOptions, double yawDegrees,
                                        const EnvProjectOptions& options, EnvMap* env, size_t bandBytes) {
  checkOrder(options.order);
  EnvProjectResult result;
  ShCoeffs radiance = zeroCoeffs(options.order);
  const bool streamed = forEachLatLongBand(
      path, loadOptions, bandBytes,
      [&](EnvMap& band, int firstRow) {
        band.yawDegrees = yawDegrees;
        addProjection(runtime(), band, firstRow, env->height, options, radiance, result);
        reportProgress("env", double(firstRow + band.height) / double(std::max(env->height, 1)));
      },
      env);
  if (!streamed) {
    *env = loadEnvironment(path, loadOptions);
    env->yawDegrees = yawDegrees;
    return projectEnvironment(runtime(), *env, options);
  }
  env->yawDegrees = yawDegrees;
  finishProjection(radiance, path, options, result);
  return result;
}

ShCoeffs projectEnvironmentReference(const EnvMap& env, int order) {
  checkOrder(order);
  const int nc = order * order;
  ShCoeffs out;
  out.order = order;
  out.rgb.assign(size_t(nc), Rgb{0, 0, 0});
  std::vector<double> y(static_cast<size_t>(nc));
  const size_t count = env.texelCount();
  for (size_t t = 0; t < count; ++t) {
    double d[3], omega;
    texelDirection(env, t, d, &omega);
    shEval(order, d[0], d[1], d[2], y.data());
    const std::array<float, 3> rgb = env.texel(t);
    for (int k = 0; k < nc; ++k)
      for (int ch = 0; ch < 3; ++ch) out.rgb[size_t(k)][size_t(ch)] += double(rgb[ch]) * y[size_t(k)] * omega;
  }
  return out;
}

}  // namespace prtbake
