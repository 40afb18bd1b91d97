// Scale-out: shard specs, the partition rule and the partial transport job (see shard.h).
#include "shard.h"

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <unistd.h>

#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/hash.h"
#include "prtbake/mesh.h"

namespace prtbake::jobs {
namespace {

constexpr long kMaxShards = 100000;

bool parseNonNegative(const std::string& text, long* out) {
  if (text.empty() || text.size() > 9) return false;
  for (char c : text)
    if (c < '0' || c > '9') return false;
  *out = std::strtol(text.c_str(), nullptr, 10);
  return true;
}

// One shard's vertex range of a split transport job, against the whole mesh.
ExecResult runTransportPart(const Job& job, ExecContext& ctx) {
  const json& shard = job.params.at("shard");
  const int index = shard.at("index").get<int>(), count = shard.at("count").get<int>();
  TransportOptions options = transportOptionsFrom(job.params);
  const Mesh mesh = loadMesh(job.input, meshAlbedo(options));
  const auto [first, n] = vertexRange(mesh.vertexCount(), index, count);
  options.firstVertex = first;
  options.vertexCount = n;
  const TransportResult r = computeTransport(ctx.runtime(), mesh, options);
  const std::string bytes = transportNpyBytes(r);
  writeFileAtomic(ctx.output("npy"), bytes);
  ExecResult result;
  meshInputs(job, mesh, result);
  result.report = {{"shard", {{"index", index}, {"count", count}}},
                   {"first_vertex", first},
                   {"vertex_count", n},
                   {"mesh_vertices", mesh.vertexCount()},
                   {"order", r.order},
                   {"channels", r.channels},
                   {"partial_sha256", sha256Hex(bytes.data(), bytes.size())},
                   {"samples", r.samples},
                   {"rays", r.rays},
                   {"total_samples", r.totalSamples},
                   {"vertices_unoccludable", r.verticesUnoccludable},
                   {"standard_error_max", r.maxStdError},
                   {"standard_error_mean", r.meanStdError},
                   {"bvh_nodes", r.bvhNodes},
                   {"degenerate_triangles", r.degenerateTriangles},
                   {"vertices_without_normal", r.verticesWithoutNormal},
                   {"device", r.device},
                   {"timings", {{"bvh_seconds", r.bvhSeconds}, {"kernel_seconds", r.kernelSeconds},
                                {"total_seconds", r.totalSeconds}}}};
  return result;
}

const JobType& partialType() {
  static const JobType type = [] {
    JobType t;
    t.name = "transport_shard";
    t.input = InputKind::File;
    t.outputKinds = {"npy"};
    t.execute = runTransportPart;
    return t;
  }();
  return type;
}

}  // namespace

ShardSpec parseShardSpec(const std::string& text, const std::string& option) {
  const auto slash = text.find('/');
  const std::string usage = "expected I/N with 0 <= I < N (or auto/N), got '" + text + "'";
  if (slash == std::string::npos) throw UsageError(option, usage);
  long index = 0, count = 0;
  if (!parseNonNegative(text.substr(slash + 1), &count) || count < 1 || count > kMaxShards)
    throw UsageError(option, usage);
  std::string indexText = text.substr(0, slash);
  if (indexText == "auto") {
    const char* names[] = {"SLURM_ARRAY_TASK_ID", "JOB_COMPLETION_INDEX"};
    indexText.clear();
    for (const char* name : names)
      if (const char* v = std::getenv(name); v && *v) {
        indexText = v;
        break;
      }
    if (indexText.empty())
      throw UsageError(option, "auto needs $SLURM_ARRAY_TASK_ID or $JOB_COMPLETION_INDEX, and neither is set");
  }
  if (!parseNonNegative(indexText, &index) || index >= count) throw UsageError(option, usage);
  return {int(index), int(count)};
}

std::pair<size_t, size_t> vertexRange(size_t vertices, int index, int count) {
  const auto bound = [&](int i) { return size_t((unsigned __int128)vertices * unsigned(i) / unsigned(count)); };
  return {bound(index), bound(index + 1) - bound(index)};
}

std::string partialPath(const Job& job, int index, int count) {
  return job.outputs.front().path + ".shard-" + std::to_string(index) + "-of-" + std::to_string(count) + ".npy";
}

std::string failureMarkerPath(const Job& job, int index, int count) {
  return job.outputs.front().path + ".shard-" + std::to_string(index) + "-of-" + std::to_string(count) +
         ".failed.json";
}

Job partialJob(const Job& job, ShardSpec s) {
  Job part = job;
  part.type = job.type->name == "glossy"     ? &glossyPartialType()
              : job.type->name == "probes"   ? &probesPartialType()
              : job.type->name == "lightmap" ? &lightmapPartialType()
                                             : &partialType();
  part.label = job.label + " [shard " + s.name() + "]";
  part.outputs = {{"npy", partialPath(job, s.index, s.count)}};
  part.manifestPath = part.outputs.front().path + ".manifest.json";
  part.params["shard"] = {{"index", s.index}, {"count", s.count}};
  part.failureMarker = failureMarkerPath(job, s.index, s.count);
  return part;
}

std::vector<float> readPartialNpy(const std::string& path, size_t* vertices, size_t* columns) {
  // Exactly what transportNpyBytes writes: version 1.0, '<f4', C order, 2-D shape.
  const std::string bytes = readFile(path);
  auto bad = [&](const std::string& what) { return InputError(path, "not a partial result: " + what); };
  if (bytes.size() < 10 || bytes.compare(0, 8, std::string("\x93NUMPY\x01\x00", 8)) != 0) throw bad("no .npy header");
  const size_t headerLen = size_t(uint8_t(bytes[8])) | size_t(uint8_t(bytes[9])) << 8;
  if (bytes.size() < 10 + headerLen) throw bad("truncated header");
  const std::string header = bytes.substr(10, headerLen);
  if (header.find("'descr': '<f4'") == std::string::npos || header.find("'fortran_order': False") == std::string::npos)
    throw bad("expected little-endian float32 in C order");
  const auto open = header.find("'shape': (");
  if (open == std::string::npos) throw bad("no shape");
  unsigned long long v = 0, c = 0;
  if (std::sscanf(header.c_str() + open + 10, "%llu, %llu)", &v, &c) != 2) throw bad("expected a 2-D shape");
  const size_t data = 10 + headerLen;
  if (bytes.size() - data != size_t(v) * size_t(c) * 4) throw bad("data size does not match the shape");
  std::vector<float> out(size_t(v) * size_t(c));
  if (!out.empty()) std::memcpy(out.data(), bytes.data() + data, out.size() * 4);
  *vertices = size_t(v);
  *columns = size_t(c);
  return out;
}

Mesh loadMergedMesh(const Job& job, size_t vertices) {
  Mesh mesh = loadMesh(job.input);
  if (mesh.vertexCount() != vertices)
    throw InputError(job.input, "has " + std::to_string(mesh.vertexCount()) + " vertices, the shards saw " +
                                    std::to_string(vertices));
  return mesh;
}

void removeOldManifest(const Job& job) {
  if (::unlink(job.manifestPath.c_str()) != 0 && errno != ENOENT)
    throw OutputError(job.manifestPath, std::string("cannot remove the old manifest: ") + std::strerror(errno));
}

void writeMergedManifest(const Job& job, const json& shardManifest, const std::string& device, double shardSeconds,
                         const json& report) {
  std::vector<InputHash> inputs;
  for (const auto& in : shardManifest["inputs"])
    inputs.push_back({in.value("path", std::string()), in.value("sha256", std::string())});
  const json manifest = makeManifest(job, inputs, device, {{"shard_total_seconds", shardSeconds}}, report);
  writeFileAtomic(job.manifestPath, manifest.dump(2) + "\n");
}

}  // namespace prtbake::jobs
