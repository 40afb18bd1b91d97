// Prefiltered specular environments: options, schedules and the device driver.
#include "prtbake/prefilter.h"
#include "prtbake/progress.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <map>
#include <memory>

#include "core/kernel_options.h"
#include "core/parallel.h"
#include "prefilter/prefilter_detail.h"
#include "prtbake/clock.h"
#include "prtbake/error.h"
#include "prtbake/limits.h"
#include "prtbake/lut.h"

namespace prtbake {
namespace {

// Texels per face recomputed for the error estimate (whole leaves spread over the face: 16 of
// 8×8 or 4 of 16×16).
constexpr size_t kEstimateTexelsPerFace = 1024;
// The first per-bin tolerance, relative to the target, and the most passes per level. On the
// four HDR maps the 99th percentile of a level's error is 0.1 to 1 times the per-bin
// tolerance (narrow lobes lower, r = 1 near 1), so most levels take one pass.
constexpr double kFirstBinTolerance = 2.0;
constexpr int kMaxPasses = 4;
// A ring's (Charlie's) leaves are cut and computed in blocks of this many leaves a side (256 or
// 512 texels): its bins lie in each texel's own thin band, so a leaf's lists are long (11,900
// bins per texel at r = 0, 256², venice_sunset_1k.hdr) and a large level's would not fit at once.
constexpr int kRingChunkLeaves = 32;
// Babylon's α_G = r² + 0.0005 (pbrHelperFunctions: the smallest α its shaders use).
constexpr double kBabylonAlphaOffset = 0.0005;

int maxLevelsFor(int base) {
  int levels = 1;
  while ((base >> levels) >= 1) ++levels;
  return levels;
}

int defaultLevels(const PrefilterOptions& o) {
  if (o.schedule == PrefilterSchedule::Explicit) return int(o.roughness.size());
  if (o.lobe == PrefilterLobe::Lambertian) return 1;
  if (o.baseSize <= 16) return maxLevelsFor(o.baseSize);
  int n = 1;
  while ((o.baseSize >> n) >= 16) ++n;
  return n;
}

std::string listText(const std::vector<double>& v) {
  std::string s;
  for (double x : v) s += (s.empty() ? "" : ",") + std::to_string(x);
  return s;
}

}  // namespace

const char* toString(PrefilterLobe lobe) {
  switch (lobe) {
    case PrefilterLobe::Ggx: return "ggx";
    case PrefilterLobe::Charlie: return "charlie";
    case PrefilterLobe::Lambertian: return "lambertian";
  }
  return "?";
}

const char* toString(PrefilterSchedule s) {
  switch (s) {
    case PrefilterSchedule::Linear: return "linear";
    case PrefilterSchedule::Filament: return "filament";
    case PrefilterSchedule::Babylon: return "babylon";
    case PrefilterSchedule::Explicit: return "explicit";
  }
  return "?";
}

const char* toString(PrefilterMethod m) { return m == PrefilterMethod::Cut ? "cut" : "sampled"; }

PrefilterLobe parsePrefilterLobe(const std::string& t, const std::string& subject) {
  if (t == "ggx") return PrefilterLobe::Ggx;
  if (t == "charlie") return PrefilterLobe::Charlie;
  if (t == "lambertian") return PrefilterLobe::Lambertian;
  throw UsageError(subject, "unknown lobe '" + t + "' (expected ggx|charlie|lambertian)");
}

PrefilterSchedule parsePrefilterSchedule(const std::string& t, const std::string& subject) {
  if (t == "linear") return PrefilterSchedule::Linear;
  if (t == "filament") return PrefilterSchedule::Filament;
  if (t == "babylon") return PrefilterSchedule::Babylon;
  if (t == "explicit") return PrefilterSchedule::Explicit;
  throw UsageError(subject, "unknown schedule '" + t + "' (expected linear|filament|babylon, or --roughness R0,R1,...)");
}

PrefilterMethod parsePrefilterMethod(const std::string& t, const std::string& subject) {
  if (t == "cut") return PrefilterMethod::Cut;
  if (t == "sampled") return PrefilterMethod::Sampled;
  throw UsageError(subject, "unknown method '" + t + "' (expected cut|sampled)");
}

void validatePrefilterOptions(const PrefilterOptions& o) {
  if (o.baseSize < 1 || o.baseSize > kPrefilterMaxSize)
    throw UsageError("--size", std::to_string(o.baseSize) + " is out of range [1, " + std::to_string(kPrefilterMaxSize) + "]");
  const int maxLevels = maxLevelsFor(o.baseSize);
  const bool expl = o.schedule == PrefilterSchedule::Explicit;
  if (o.levels < 0 || o.levels > maxLevels)
    throw UsageError("--levels", std::to_string(o.levels) + " is out of range [1, " + std::to_string(maxLevels) +
                                     "] for base size " + std::to_string(o.baseSize));
  if (expl) {
    if (o.roughness.empty()) throw UsageError("--roughness", "the explicit schedule needs a list of roughness values");
    if (int(o.roughness.size()) > maxLevels)
      throw UsageError("--roughness", std::to_string(o.roughness.size()) + " levels, but base size " +
                                          std::to_string(o.baseSize) + " has at most " + std::to_string(maxLevels));
    if (o.levels != 0 && o.levels != int(o.roughness.size()))
      throw UsageError("--levels", "disagrees with the " + std::to_string(o.roughness.size()) + " roughness values");
    for (double r : o.roughness)
      if (!(r >= 0.0 && r <= 1.0)) throw UsageError("--roughness", "every value must lie in [0, 1] (got " + listText(o.roughness) + ")");
  } else if (!o.roughness.empty()) {
    throw UsageError("--roughness", std::string("a list of roughness values is its own schedule; it cannot be combined with --schedule ") +
                                        toString(o.schedule));
  }
  if (!(o.tolerance >= 1e-4 && o.tolerance <= 0.1)) throw UsageError("--tolerance", "must lie in [1e-4, 0.1]");
  if (o.samples < 1 || o.samples > kPrefilterMaxSamples)
    throw UsageError("--samples", std::to_string(o.samples) + " is out of range [1, " + std::to_string(kPrefilterMaxSamples) + "]");
  if (o.vectorWidth != 0 && o.vectorWidth != 1 && o.vectorWidth != 8 && o.vectorWidth != 16)
    throw UsageError("vector width", "must be 1, 8 or 16");
  if (o.method == PrefilterMethod::Sampled && o.lobe != PrefilterLobe::Ggx)
    throw UsageError("--method", "the sampled method exists to compare with the anchors' GGX filtering; use --lobe ggx");
  // The chain (RGB float, plus its half or float RGBA copy for writing) must fit the limit.
  double texels = 0;
  const int levels = o.levels ? o.levels : defaultLevels(o);
  for (int i = 0; i < levels; ++i) texels += 6.0 * double(std::max(1, o.baseSize >> i)) * double(std::max(1, o.baseSize >> i));
  checkInputMemory("--size", "a prefiltered chain with base " + std::to_string(o.baseSize), texels * 28.0);
}

std::vector<PrefilterLevelSpec> prefilterLevels(const PrefilterOptions& o) {
  validatePrefilterOptions(o);
  const int n = o.levels ? o.levels : defaultLevels(o);
  std::vector<PrefilterLevelSpec> out;
  for (int i = 0; i < n; ++i) {
    PrefilterLevelSpec s;
    s.size = std::max(1, o.baseSize >> i);
    const double x = n > 1 ? double(i) / double(n - 1) : 0.0;
    switch (o.schedule) {
      case PrefilterSchedule::Linear: s.roughness = x; break;
      case PrefilterSchedule::Filament: s.roughness = 1.0 - std::sqrt(std::max(0.0, 1.0 - x)); break;
      case PrefilterSchedule::Explicit: s.roughness = o.roughness[size_t(i)]; break;
      case PrefilterSchedule::Babylon: {
        s.alpha = n > 1 ? std::pow(double(o.baseSize), x - 1.0) : 1.0 / o.baseSize;
        s.roughness = std::sqrt(std::max(0.0, s.alpha - kBabylonAlphaOffset));
        break;
      }
    }
    if (o.schedule != PrefilterSchedule::Babylon) s.alpha = s.roughness * s.roughness;
    out.push_back(s);
  }
  return out;
}

namespace detail {
// prefilter_resample.cpp: the anchors' estimator for one level.
std::vector<float> prefilterSampledLevel(Runtime& rt, const std::vector<std::vector<float>>& chain, int n, double alpha,
                                         int samples, double* kernelSeconds);
std::vector<std::vector<float>> boxChain(const std::vector<float>& base, int n);
}  // namespace detail

namespace {

const std::vector<float>& basesTable() {
  static const std::vector<float> t = [] {
    std::vector<float> v;
    for (const CubeFaceBasis& b : standardCubeBases())
      for (const auto* a : {&b.axisU, &b.axisV, &b.axisN})
        for (double x : *a) v.push_back(float(x));
    return v;
  }();
  return t;
}

}  // namespace

std::string detail::prefilterCutOptions(PrefilterLobe lobe, int vectorWidth) {
  return "-DPF_LOBE=" + std::to_string(int(lobe)) + " -DVW=" + std::to_string(vectorWidth);
}
std::string detail::prefilterSampledOptions() { return "-DVW=1"; }

namespace {

// The device side of the cut method: the tree's buffers and one kernel per lobe.
class CutRunner {
 public:
  void setProgress(double fraction) { progress_ = fraction; }
  CutRunner(Runtime& rt, const detail::BinTree& tree, PrefilterLobe lobe, int vectorWidth) : rt_(rt), tree_(tree) {
    vw_ = vectorWidth ? vectorWidth : rt.info().type == "gpu" ? 1 : 16;
    kernel_ = rt.kernel("prefilter.cl", "prefilter_cut", detail::prefilterCutOptions(lobe, vw_));
    const cl_mem_flags host = rt.info().type == "cpu" ? CL_MEM_USE_HOST_PTR : CL_MEM_COPY_HOST_PTR;
    auto buf = [&](const RawVector<float>& v) {
      return cl::Buffer(rt.context(), CL_MEM_READ_ONLY | host, v.size() * sizeof(float), const_cast<float*>(v.data()));
    };
    flux_ = buf(tree.flux), dirL_ = buf(tree.dirL), dirG_ = buf(tree.dirG);
    std::vector<uint32_t> offsets(tree.offset.begin(), tree.offset.end());
    binOffsets_ = rt.upload(offsets);
    const std::vector<float>& b = basesTable();
    bases_ = cl::Buffer(rt.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, b.size() * sizeof(float),
                        const_cast<float*>(b.data()));
  }

  // Computes the leaves leaves[face] of each face of the level into `out` (6n²·3 floats on the
  // device); returns the texel-bin evaluations. Adds host (cut) and device seconds.
  // chunkSide 0: the six faces' cuts on the host's cores at once (each a read-only walk of the
  // trees: at 256² the cut is most of a level's time), then one launch per face. Otherwise the
  // leaves go in square blocks of chunkSide² leaves, each cut and computed before the next, so
  // that only one block's lists are held (a ring's lists at 256² would take ~1 GB at once).
  size_t run(const detail::LobeScale& scale, cl_float4 lobe, const detail::TileTree& tt,
             const std::vector<std::vector<int>>& leaves, cl::Buffer& out, double* cutSeconds, double* kernelSeconds,
             int chunkSide = 0) {
    cl::Buffer offsets = rt_.upload(tt.offset);
    size_t summed = 0;
    if (chunkSide > 0) {
      for (int face = 0; face < 6; ++face) {
        std::map<int, std::vector<int>> blocks;  // by block index, leaves in order
        for (int leaf : leaves[size_t(face)]) {
          const int ty = leaf / tt.side(0), tx = leaf % tt.side(0);
          blocks[(ty / chunkSide) * tt.side(0) + tx / chunkSide].push_back(leaf);
        }
        for (const auto& [key, part] : blocks) {
          const auto t0 = std::chrono::steady_clock::now();
          const detail::TileCuts cuts = detail::buildTileCuts(tree_, scale, tt, face, part);
          *cutSeconds += secondsSince(t0);
          const auto t1 = std::chrono::steady_clock::now();
          summed += launch(cuts, tt, face, part, offsets, lobe, out);
          rt_.queue().finish();
          keep_.clear();
          *kernelSeconds += secondsSince(t1);
        }
      }
      return summed;
    }
    const auto t0 = std::chrono::steady_clock::now();
    std::vector<detail::TileCuts> cuts(6);
    detail::parallelEach(6, 6, [&](size_t face) {
      const std::vector<int>& part = leaves[face];
      if (part.empty()) return;
      // Every leaf of the face: cut every tile (an empty list); a subset: only the tiles above it.
      const bool whole = part.size() == allLeaves(tt).size();
      cuts[face] = detail::buildTileCuts(tree_, scale, tt, int(face), whole ? std::vector<int>{} : part);
    });
    *cutSeconds += secondsSince(t0);
    const auto t1 = std::chrono::steady_clock::now();
    for (int face = 0; face < 6; ++face)
      if (!leaves[size_t(face)].empty())
        summed += launch(cuts[size_t(face)], tt, face, leaves[size_t(face)], offsets, lobe, out);
    rt_.queue().finish();
    keep_.clear();
    *kernelSeconds += secondsSince(t1);
    return summed;
  }

  // Enqueues the leaves `part` of one face with their cut; returns the texel-bin evaluations.
  // The lists' buffers stay alive (keep_) until the caller has finished the queue.
  size_t launch(const detail::TileCuts& c, const detail::TileTree& tt, int face, const std::vector<int>& part,
                cl::Buffer& offsets, cl_float4 lobe, cl::Buffer& out) {
    const int wiPerLeaf = (tt.leaf * tt.leaf + vw_ - 1) / vw_;
    size_t summed = 0;
    for (int leaf : part)
      for (int k = 0; k < tt.levels; ++k) {
        const uint32_t id = tt.id(k, face, (leaf / tt.side(0)) >> k, (leaf % tt.side(0)) >> k);
        for (uint32_t e = c.start[id]; e < c.start[id + 1]; ++e)
          summed += (size_t(1) << (2 * ((c.bins[e] >> 23) & 15u))) * size_t(tt.leaf * tt.leaf);
      }
    cl::Buffer start = rt_.upload(c.start), bins = rt_.upload(c.bins), ids = rt_.upload(part);
    keep_.insert(keep_.end(), {start, bins, ids});
    int a = 0;
    kernel_.setArg(a++, flux_);
    kernel_.setArg(a++, dirL_);
    kernel_.setArg(a++, dirG_);
    kernel_.setArg(a++, start);
    kernel_.setArg(a++, bins);
    kernel_.setArg(a++, ids);
    kernel_.setArg(a++, face);
    kernel_.setArg(a++, tt.n);
    kernel_.setArg(a++, tt.leaf);
    kernel_.setArg(a++, wiPerLeaf);
    kernel_.setArg(a++, tt.levels);
    kernel_.setArg(a++, offsets);
    kernel_.setArg(a++, tt.side(0));
    kernel_.setArg(a++, binOffsets_);
    kernel_.setArg(a++, tree_.faceSize0);
    kernel_.setArg(a++, bases_);
    kernel_.setArg(a++, lobe);
    kernel_.setArg(a++, out);
    rt_.queue().enqueueNDRangeKernel(kernel_, cl::NullRange, cl::NDRange(part.size() * size_t(wiPerLeaf)),
                                     cl::NDRange(size_t(wiPerLeaf)));
    if (progressWanted()) {  // a cancellation point per launch (the level's fraction is the caller's)
      rt_.queue().finish();
      reportProgress("prefilter", progress_);
    }
    return summed;
  }

  // The leaves of one face that exist (start inside the level).
  static std::vector<int> allLeaves(const detail::TileTree& tt) {
    std::vector<int> v;
    for (int ty = 0; ty < tt.side(0); ++ty)
      for (int tx = 0; tx < tt.side(0); ++tx)
        if (ty * tt.leaf < tt.n && tx * tt.leaf < tt.n) v.push_back(ty * tt.side(0) + tx);
    return v;
  }

 private:
  Runtime& rt_;
  double progress_ = 0;  // the chain's fraction done before this level, for reportProgress
  const detail::BinTree& tree_;
  int vw_ = 16;
  cl::Kernel kernel_;
  cl::Buffer flux_, dirL_, dirG_, bases_, binOffsets_;
  std::vector<cl::Buffer> keep_;  // enqueued launches' lists
};

cl_float4 lobeParams(PrefilterLobe lobe, double alpha) {
  cl_float4 p{};
  p.s[0] = float(alpha * alpha);
  if (lobe == PrefilterLobe::Charlie) {
    const double a = 1.0 / (2.0 * alpha), m = 1.0 / (1.0 + a);
    p.s[1] = float(a);
    p.s[2] = float((std::log(m) + a * std::log(0.5 * (1.0 - m))) / std::log(2.0));
  }
  return p;
}

// Relative difference of a against b, max over channels, with a floor for black texels.
double relativeDiff(const float* a, const float* b, double floor) {
  double worst = 0;
  for (int c = 0; c < 3; ++c)
    worst = std::max(worst, std::abs(double(a[c]) - double(b[c])) / std::max(double(std::abs(b[c])), floor));
  return worst;
}

// The error estimate of a level: |P − P'|/P' × 4/3 over the subset's texels, P' the subset
// recomputed with a quarter of the per-bin error bound (the cut's error is of second order in
// the bin size, so it falls 4× and P − P' is 3/4 of P's error).
PrefilterErrorEstimate estimateError(const std::vector<float>& rgb, const std::vector<float>& ref,
                                     const detail::TileTree& tt, const std::vector<std::vector<int>>& subset) {
  const int n = tt.n;
  double mean = 0;
  for (float v : rgb) mean += std::abs(double(v));
  const double floor = std::max(1e-30, 1e-6 * mean / double(rgb.size()));
  std::vector<double> rel;
  for (int face = 0; face < 6; ++face)
    for (int leaf : subset[size_t(face)]) {
      const int ty = leaf / tt.side(0), tx = leaf % tt.side(0);
      for (int r = ty * tt.leaf; r < std::min(n, (ty + 1) * tt.leaf); ++r)
        for (int c = tx * tt.leaf; c < std::min(n, (tx + 1) * tt.leaf); ++c) {
          const size_t i = 3 * ((size_t(face) * size_t(n) + size_t(r)) * size_t(n) + size_t(c));
          rel.push_back(relativeDiff(&rgb[i], &ref[i], floor) * 4.0 / 3.0);
        }
    }
  std::sort(rel.begin(), rel.end());
  PrefilterErrorEstimate e;
  double sum = 0;
  for (double x : rel) sum += x;
  e.texels = rel.size();
  e.mean = rel.empty() ? 0 : sum / double(rel.size());
  e.p99 = rel.empty() ? 0 : rel[std::min(rel.size() - 1, size_t(0.99 * double(rel.size())))];
  e.max = rel.empty() ? 0 : rel.back();
  return e;
}

}  // namespace

namespace {

// The leaves whose texels the error estimate recomputes: kEstimateTexelsPerFace texels' worth
// of each face's leaves, spread over it.
std::vector<std::vector<int>> estimateLeaves(const detail::TileTree& tt, const std::vector<int>& faceLeaves) {
  const size_t perFace =
      std::min(faceLeaves.size(), std::max<size_t>(1, kEstimateTexelsPerFace / size_t(tt.leaf * tt.leaf)));
  std::vector<std::vector<int>> subset(6);
  for (size_t f = 0; f < 6; ++f) {
    for (size_t i = 0; i < perFace; ++i)
      subset[f].push_back(faceLeaves[(i * faceLeaves.size() + f * 7) / perFace % faceLeaves.size()]);
    std::sort(subset[f].begin(), subset[f].end());
    subset[f].erase(std::unique(subset[f].begin(), subset[f].end()), subset[f].end());
  }
  return subset;
}

// One level by the cut, at level.alphaUsed: the per-bin tolerance starts at
// kFirstBinTolerance × the target and halves while the estimated 99th percentile (the
// estimate's leaves again with every bin error bound divided by 4) misses the target.
void cutLevel(Runtime& rt, CutRunner& runner, const PrefilterOptions& options, PrefilterLevel& level) {
  const int n = level.spec.size;
  const cl_float4 params = lobeParams(options.lobe, level.alphaUsed);
  const size_t texels = size_t(6) * size_t(n) * size_t(n);
  cl::Buffer out(rt.context(), CL_MEM_WRITE_ONLY, texels * 3 * sizeof(float));
  cl::Buffer check;
  const bool ring = options.lobe == PrefilterLobe::Charlie;
  const detail::TileTree tt = detail::makeTileTree(n);
  const int chunk = ring ? kRingChunkLeaves : 0;
  const std::vector<int> faceLeaves = CutRunner::allLeaves(tt);
  const std::vector<std::vector<int>> all(6, faceLeaves);
  const std::vector<std::vector<int>> subset = estimateLeaves(tt, faceLeaves);
  double eps = kFirstBinTolerance * options.tolerance;
  for (int pass = 0;; ++pass) {
    const detail::LobeScale scale(options.lobe, level.alphaUsed, eps);
    level.binsSummed = runner.run(scale, params, tt, all, out, &level.cutSeconds, &level.kernelSeconds, chunk);
    level.rgb.resize(texels * 3);
    rt.queue().enqueueReadBuffer(out, CL_TRUE, 0, level.rgb.size() * sizeof(float), level.rgb.data());
    level.binTolerance = eps;
    level.passes = pass + 1;
    if (!options.errorEstimate) break;
    const detail::LobeScale fine(options.lobe, level.alphaUsed, eps / 4);
    if (pass == 0) check = cl::Buffer(rt.context(), CL_MEM_WRITE_ONLY, texels * 3 * sizeof(float));
    double cutS = 0, kernelS = 0;
    runner.run(fine, params, tt, subset, check, &cutS, &kernelS, chunk);
    level.estimateSeconds += cutS + kernelS;
    std::vector<float> ref(texels * 3);
    rt.queue().enqueueReadBuffer(check, CL_TRUE, 0, ref.size() * sizeof(float), ref.data());
    level.error = estimateError(level.rgb, ref, tt, subset);
    if (level.error.p99 <= options.tolerance || pass + 1 >= kMaxPasses) break;
    eps /= 2;
  }
}

}  // namespace

namespace {

bool isResampled(PrefilterLobe lobe, const PrefilterLevelSpec& s) { return lobe == PrefilterLobe::Ggx && s.alpha == 0.0; }

// Whether a level is filtered by the cut (and so needs the bin tree).
bool needsTree(const PrefilterOptions& options, const std::vector<PrefilterLevelSpec>& specs) {
  if (options.method == PrefilterMethod::Sampled) return false;
  for (const auto& s : specs)
    if (!isResampled(options.lobe, s)) return true;
  return false;
}

// The face sizes the chain resamples the source to: its r = 0 levels, and the sampled
// method's base.
std::vector<int> resampledSizes(const PrefilterOptions& options, const std::vector<PrefilterLevelSpec>& specs) {
  std::vector<int> sizes;
  if (options.method == PrefilterMethod::Sampled) sizes.push_back(options.baseSize);
  for (const auto& s : specs)
    if (isResampled(options.lobe, s)) sizes.push_back(s.size);
  std::sort(sizes.begin(), sizes.end());
  sizes.erase(std::unique(sizes.begin(), sizes.end()), sizes.end());
  return sizes;
}

// The chain of `env` (its description: layout, size, yaw, source) from the source's two
// digests: tree() builds the bin tree (called once, only when a level needs it) and
// resampled(n) the r = 0 resampling of face size n (once per size of resampledSizes).
// Their times go to binSeconds and resampleSeconds. The device (runtime()) is asked for once
// the tree is built, so that what building it frees is free before the device starts.
PrefilterResult prefilterChain(const std::function<Runtime&()>& runtime, const EnvMap& env,
                               const PrefilterOptions& options,
                               const std::function<detail::BinTree()>& tree,
                               const std::function<std::vector<float>(int n)>& resampled) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<PrefilterLevelSpec> specs = prefilterLevels(options);
  PrefilterResult result;
  result.options = options;
  result.sourceTexels = (long long)env.texelCount();
  const PrefilterLobe lobe = options.lobe;
  const bool sampled = options.method == PrefilterMethod::Sampled;

  // Sampled: the chain of the base cube; cut: the bin tree (only when some level needs it).
  std::vector<std::vector<float>> chain;
  detail::BinTree bins;
  const bool needTree = needsTree(options, specs);
  auto resample = [&](int n) {
    const auto tr = std::chrono::steady_clock::now();
    std::vector<float> rgb = resampled(n);
    result.resampleSeconds += secondsSince(tr);
    return rgb;
  };
  if (sampled) {
    chain = detail::boxChain(resample(options.baseSize), options.baseSize);
  } else if (needTree) {
    const auto tb = std::chrono::steady_clock::now();
    result.binFaceSize = detail::binFaceSizeFor(env);
    bins = tree();
    PRTBAKE_CHECK(bins.faceSize0 == result.binFaceSize, "the bin tree has the source's finest bin size");
    result.binSeconds = secondsSince(tb);
  }
  Runtime& rt = runtime();
  result.device = rt.deviceLabel();
  const double build0 = rt.buildSeconds();
  // Lobes narrower than half the larger of a source texel and a finest bin would see one
  // bin at a time (a nearest-texel lookup that jumps at bin edges): they are widened to it.
  result.alphaFloor = 0.5 * std::max(detail::sourceTexelAngle(env), result.binFaceSize ? 2.0 / result.binFaceSize : 0.0);
  std::unique_ptr<CutRunner> runner;
  if (needTree) runner = std::make_unique<CutRunner>(rt, bins, lobe, options.vectorWidth);

  for (const PrefilterLevelSpec& spec : specs) {
    PrefilterLevel level;
    level.spec = spec;
    const int n = spec.size;
    if (isResampled(lobe, spec)) {
      level.rgb = sampled && n == options.baseSize ? chain[0] : resample(n);
      level.alphaUsed = 0;
    } else if (sampled) {
      level.alphaUsed = spec.alpha;
      level.rgb = detail::prefilterSampledLevel(rt, chain, n, spec.alpha, options.samples, &level.kernelSeconds);
      level.binsSummed = size_t(6) * size_t(n) * size_t(n) * size_t(options.samples);
    } else {
      level.alphaUsed = lobe == PrefilterLobe::Ggx       ? std::max(spec.alpha, result.alphaFloor)
                        : lobe == PrefilterLobe::Charlie ? std::max(spec.alpha, kLutClothAlphaMin)
                                                         : 1.0;
      runner->setProgress(double(result.levels.size()) / double(specs.size()));
      cutLevel(rt, *runner, options, level);
    }
    for (float v : level.rgb)
      if (!std::isfinite(v) || v < 0.0f)
        throw InputError(env.source.empty() ? "environment" : env.source,
                         "prefiltering produced a non-finite or negative value (radiance too large for float?)");
    result.kernelSeconds += level.kernelSeconds;
    result.levels.push_back(std::move(level));
    reportProgress("prefilter", double(result.levels.size()) / double(specs.size()));
  }
  result.buildSeconds = rt.buildSeconds() - build0;
  result.totalSeconds = secondsSince(t0);
  return result;
}

// The chain of a map held whole.
PrefilterResult prefilterWhole(const std::function<Runtime&()>& runtime, const EnvMap& env,
                               const PrefilterOptions& options) {
  prefilterLevels(options);  // validates
  if (env.texelCount() == 0 || env.rgb.size() != 3 * env.texelCount())
    throw InputError(env.source.empty() ? "environment" : env.source, "empty or inconsistent environment");
  return prefilterChain(
      runtime, env, options, [&] { return detail::buildBinTree(env, detail::binFaceSizeFor(env)); },
      [&](int n) { return resampleEnvironment(env, n); });
}

}  // namespace

PrefilterResult prefilterEnvironment(Runtime& rt, const EnvMap& env, const PrefilterOptions& options) {
  return prefilterWhole([&]() -> Runtime& { return rt; }, env, options);
}

PrefilterResult prefilterEnvironmentFile(const std::function<Runtime&()>& runtime, const std::string& path,
                                         const EnvLoadOptions& loadOptions, double yawDegrees,
                                         const PrefilterOptions& options, EnvMap* env, size_t bandBytes) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<PrefilterLevelSpec> specs = prefilterLevels(options);  // validates before reading
  const bool needTree = needsTree(options, specs);
  const std::vector<int> sizes = resampledSizes(options, specs);
  // A map that comes as one band is kept whole and prefiltered as loadEnvironment's; otherwise
  // every band goes into the bin sums and the resamplings, and is dropped.
  EnvMap whole;
  bool oneBand = false;
  std::unique_ptr<detail::BinTreeBands> binBands;
  std::vector<std::unique_ptr<detail::ResampleBands>> resampleBands;
  double binSeconds = 0, resampleSeconds = 0;
  auto digest = [&](EnvMap& band, int row) {
    band.toFloat();
    if (resampleBands.empty() && !binBands) {
      EnvMap& description = *env;
      description.yawDegrees = yawDegrees;
      if (needTree) binBands = std::make_unique<detail::BinTreeBands>(description, detail::binFaceSizeFor(description));
      for (int n : sizes) resampleBands.push_back(std::make_unique<detail::ResampleBands>(description, n));
    }
    const auto tb = std::chrono::steady_clock::now();
    if (binBands) binBands->add(band.rgb.data(), size_t(row) * size_t(band.width), band.texelCount());
    binSeconds += secondsSince(tb);
    const auto tr = std::chrono::steady_clock::now();
    for (auto& r : resampleBands) r->add(band, row);
    resampleSeconds += secondsSince(tr);
  };
  const bool streamed = forEachLatLongBand(
      path, loadOptions, bandBytes,
      [&](EnvMap& band, int row) {
        if (row == 0 && band.height == env->height) {
          whole = std::move(band), oneBand = true;
          return;
        }
        digest(band, row);
        reportProgress("prefilter", 0.0);  // a cancellation point per band (the levels' fractions follow)
      },
      env);
  if (!streamed || oneBand) {
    if (!streamed) {
      *env = loadEnvironment(path, loadOptions);
    } else {  // one band: the whole map
      env->rgb = std::move(whole.rgb);
      env->halfRgb = std::move(whole.halfRgb);
      env->toFloat();
    }
    env->yawDegrees = yawDegrees;
    return prefilterWhole(runtime, *env, options);
  }
  env->yawDegrees = yawDegrees;
  PrefilterResult result = prefilterChain(
      runtime, *env, options, [&] { return binBands->finish(); },
      [&](int n) {
        const size_t i = size_t(std::find(sizes.begin(), sizes.end(), n) - sizes.begin());
        PRTBAKE_CHECK(i < sizes.size() && resampleBands[i], "each resampled size is read in bands once");
        std::vector<float> rgb = resampleBands[i]->finish();
        resampleBands[i].reset();
        return rgb;
      });
  binBands.reset();
  result.binSeconds += binSeconds;
  result.resampleSeconds += resampleSeconds;
  result.totalSeconds = secondsSince(t0);
  return result;
}

}  // namespace prtbake
