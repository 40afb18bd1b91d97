// prtbake rotate: rotate an SH coefficient file.
#include <nlohmann/json.hpp>

#include "cli.h"
#include "prtbake/env.h"
#include "prtbake/error.h"
#include "prtbake/sh_rotate.h"

namespace prtbake::cli {
namespace {

int runRotate(const CommandLine& cl) {
  const std::string input = cl.positional.at(0);
  const std::string output = cl.get("output");
  if (output.empty()) throw UsageError("rotate", "missing -o OUT.json");
  if (cl.has("euler-zyz") == cl.has("quat")) throw UsageError("rotate", "give exactly one of --euler-zyz and --quat");
  const std::string method = cl.getChoice("method", "exact", {"exact", "projection"});
  Rotation r;
  nlohmann::json rotation;
  if (cl.has("euler-zyz")) {
    const auto a = cl.getDoubles("euler-zyz", 3);
    r = rotationFromEulerZYZ(a[0], a[1], a[2]);
    rotation = {{"euler_zyz_degrees", a}};
  } else {
    const auto q = cl.getDoubles("quat", 4);
    r = rotationFromQuaternion(q[0], q[1], q[2], q[3]);
    rotation = {{"quaternion_wxyz", q}};
  }
  std::string metaText;
  const ShCoeffs in = readShJson(input, &metaText);
  double cond = 1.0;
  const ShRotationBlocks m = method == "exact" ? shRotationExact(r, in.order)
                                               : shRotationProjection(r, in.order, {}, 1e8, &cond);
  const ShCoeffs out = applyShRotation(in, m);
  nlohmann::json meta = nlohmann::json::parse(metaText);
  meta.erase("conventions");
  rotation["method"] = method;
  rotation["matrix_row_major"] = r.m;
  rotation["meaning"] = "L'(w) = L(R^T w): the environment turned by R";
  if (method == "projection") rotation["worst_condition_number"] = cond;
  meta["rotations"].push_back(rotation);
  writeShJson(output, out, meta.dump());
  status(cl, "wrote " + output);
  return 0;
}

PRTBAKE_COMMAND(Command{"rotate", "rotate SH coefficients (exact or projection method)",
                        "prtbake rotate IN.json -o OUT.json (--euler-zyz A,B,C | --quat W,X,Y,Z) [--method exact|projection]\n"
                        "R = Rz(A)·Ry(B)·Rz(C) in degrees, or the unit quaternion W,X,Y,Z; the environment is turned by R.",
                        {{"output", true, "output JSON (also -o)"},
                         {"euler-zyz", true, "A,B,C: Euler angles in degrees, R = Rz(A) Ry(B) Rz(C)"},
                         {"quat", true, "W,X,Y,Z: rotation quaternion (normalised)"},
                         {"method", true, "exact (Ivanic-Ruedenberg, default) or projection (2l+1 directions per band)"}},
                        1, 1, runRotate});

}  // namespace
}  // namespace prtbake::cli
