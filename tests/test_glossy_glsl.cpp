// The documented GLSL (docs/glsl/prt_glossy.glsl) run in headless Chromium (WebGL 2 on
// SwiftShader) for known inputs, against prtbake's own shading of the same bake:
// uncompressed matrices and the CPCA form (int8 weights).
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "prtbake/glossy.h"
#include "prtbake/mesh.h"
#include "prtbake/sh.h"
#include "test_common.h"

using namespace prtbake;

namespace {

std::string readText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// The page: the GLSL under test inlined into a fragment shader that shades test case c
// (x = c) with the uncompressed matrices (row y = 0) and the CPCA form (y = 1) into a float
// framebuffer, read back and given as "RESULT [...]" (window.result, as test::chromiumPage reads it).
const char* kPage = R"HTML(<!DOCTYPE html><html><body><pre id="out">no result</pre><script>
const D = __DATA__;
const GLSL = __GLSL__;
const out = document.getElementById('out');
try {
  const canvas = document.createElement('canvas');
  const gl = canvas.getContext('webgl2');
  if (!gl) throw new Error('no WebGL 2');
  if (!gl.getExtension('EXT_color_buffer_float')) throw new Error('no EXT_color_buffer_float');
  const NC = D.cases, P = D.vectors;
  const vs = '#version 300 es\nin vec2 p; void main() { gl_Position = vec4(p, 0.0, 1.0); }';
  const fs = '#version 300 es\nprecision highp float; precision highp int; precision highp sampler2D;\n' +
    '#define PRT_ORDER_OUT ' + D.orderOut + '\n#define PRT_ORDER_IN ' + D.orderIn + '\n' + GLSL + '\n' +
    'uniform sampler2D uM; uniform sampler2D uU; uniform vec3 uLight[PRT_N_IN]; uniform float uG[PRT_ORDER_OUT];\n' +
    'uniform vec3 uN[' + NC + ']; uniform vec3 uV[' + NC + ']; uniform vec3 uAlb[' + NC + '];\n' +
    'uniform int uVert[' + NC + ']; uniform int uClu[' + NC + ']; uniform int uNorm[' + NC + '];\n' +
    'uniform float uW[' + (NC * P) + '];\nout vec4 o;\n' +
    'void main() { int c = int(gl_FragCoord.x); int row = int(gl_FragCoord.y); vec3 t[PRT_N_OUT];\n' +
    '  if (row == 0) prtTransfer(uM, uVert[c], uLight, t);\n' +
    '  else { float w[PRT_CPCA_VECTORS]; for (int p = 0; p < PRT_CPCA_VECTORS; ++p) w[p] = p < ' + P + ' ? uW[c * ' + P + ' + p] : 0.0;\n' +
    '         prtTransferCpca(uU, uClu[c], ' + P + ', w, t); }\n' +
    '  o = vec4(prtGlossyShade(t, uG, normalize(uN[c]), normalize(uV[c]), uAlb[c], uNorm[c] == 1), 1.0); }\n';
  function shader(type, src) {
    const s = gl.createShader(type); gl.shaderSource(s, src); gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  }
  const prog = gl.createProgram();
  gl.attachShader(prog, shader(gl.VERTEX_SHADER, vs));
  gl.attachShader(prog, shader(gl.FRAGMENT_SHADER, fs));
  gl.linkProgram(prog);
  if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(prog));
  gl.useProgram(prog);
  function texture(unit, internal, format, w, h, data) {
    const t = gl.createTexture(); gl.activeTexture(gl.TEXTURE0 + unit); gl.bindTexture(gl.TEXTURE_2D, t);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texImage2D(gl.TEXTURE_2D, 0, internal, w, h, 0, format, gl.FLOAT, new Float32Array(data));
  }
  texture(0, gl.R32F, gl.RED, D.nIn, D.matrixRows, D.matrices);
  texture(1, gl.RGBA32F, gl.RGBA, D.nOut, D.clusterRows, D.clusterLight);
  const u = (n) => gl.getUniformLocation(prog, n);
  gl.uniform1i(u('uM'), 0); gl.uniform1i(u('uU'), 1);
  gl.uniform3fv(u('uLight'), D.light); gl.uniform1fv(u('uG'), D.lobe);
  gl.uniform3fv(u('uN'), D.normal); gl.uniform3fv(u('uV'), D.view); gl.uniform3fv(u('uAlb'), D.albedo);
  gl.uniform1iv(u('uVert'), D.vertex); gl.uniform1iv(u('uClu'), D.cluster); gl.uniform1iv(u('uNorm'), D.normalised);
  gl.uniform1fv(u('uW'), D.weights);
  const fb = gl.createFramebuffer(); gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
  gl.activeTexture(gl.TEXTURE2);  // units 0 and 1 hold the inputs
  const rt = gl.createTexture(); gl.bindTexture(gl.TEXTURE_2D, rt);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, NC, 2, 0, gl.RGBA, gl.FLOAT, null);
  gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, rt, 0);
  gl.viewport(0, 0, NC, 2);
  const vb = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, vb);
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 3, -1, -1, 3]), gl.STATIC_DRAW);
  const loc = gl.getAttribLocation(prog, 'p'); gl.enableVertexAttribArray(loc);
  gl.vertexAttribPointer(loc, 2, gl.FLOAT, false, 0, 0);
  gl.drawArrays(gl.TRIANGLES, 0, 3);
  const px = new Float32Array(NC * 2 * 4);
  gl.readPixels(0, 0, NC, 2, gl.RGBA, gl.FLOAT, px);
  out.textContent = 'RESULT [' + Array.from(px).map((x) => x.toPrecision(9)).join(',') + ']';
} catch (e) {
  out.textContent = 'ERROR ' + e.message;
}
window.result = Promise.resolve(out.textContent);
</script></body></html>
)HTML";

std::string replaceAll(std::string s, const std::string& from, const std::string& to) {
  for (size_t at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size())) s.replace(at, from.size(), to);
  return s;
}

}  // namespace

TEST_CASE("GLSL: prt_glossy.glsl in headless Chromium matches prtbake's shading", "[glossy][glsl]") {
  // Both sides shade the same matrices (or the same CPCA clusters) with the same light,
  // lobe, normals and view directions: prtbake in double (shadeGlossy), the GLSL in float32
  // on SwiftShader. Float32 rounding of the sums (≤ 81 products for M l, 9 for the lobe)
  // and of the SH recurrence (measured 2.9e-7); kGlslTol = 1e-4 × (1 + |value|) leaves room
  // for other GPUs' sqrt and division. Seen failing: the GLSL lobe pairing t_lm with
  // Y_l,−m (a mirrored index) differed by 0.56; reading the matrix texture transposed
  // (texel (i, v·n_out² + j)) by 0.37 (the orders are rectangular so that it shows); int8
  // weights without their vertex scale t_v by 24.9.
  constexpr double kGlslTol = 1e-4;
  const std::string chromium = test::chromiumPath();
  if (chromium.empty())
    PRTBAKE_SKIP("chromium not found (Debian package 'chromium'; scripts/packages.sh installs it with the test packages)");
  const std::string glslPath = std::string(PRTBAKE_TEST_SOURCE_DIR) + "/../docs/glsl/prt_glossy.glsl";
  REQUIRE(test::fileExists(glslPath));

  // A small occluded scene, its order-3 shadowed matrices and a CPCA of them.
  Mesh scene = makeSquare(1.0, 0.0, 4, false);
  appendMesh(scene, makeBumpySphere(200));
  for (size_t v = 0; v < scene.vertexCount(); ++v) scene.albedo[3 * v + 1] = 0.6f;
  const int no = 3, ni = 4, no2 = no * no, ni2 = ni * ni;  // rectangular: a transposition shows
  GlossyOptions o;
  o.orderOut = no, o.orderIn = ni, o.samples = 256;
  const GlossyResult r = computeGlossyTransfer(test::runtime(), scene, o);
  // int8 weights, shaded as the GLSL's header says: c_kp folded into U, w_p = q_vp · t_v.
  CpcaOptions co;
  co.clusters = 3, co.vectors = 4, co.weightBits = 8;
  const CpcaResult c = cpcaCompress(r.matrices.data(), scene.vertexCount(), size_t(no2) * ni2, co);
  const GlossyLobe lobe = phongLobe(8.0, no);
  std::vector<double> light(size_t(ni2) * 3);
  for (int j = 0; j < ni2; ++j)
    for (int k = 0; k < 3; ++k) light[size_t(j) * 3 + k] = (j == 0 ? 2.0 : 0.6 * std::sin(1.7 * j + k));

  // The CPCA cluster-light products U_k(p+1) = c_kp b_kp l (U_k0 = μ_k l), what an
  // application uploads.
  const size_t K = size_t(c.clusters), P = size_t(c.vectors);
  std::vector<float> clusterLight;
  for (size_t k = 0; k < K; ++k)
    for (size_t p = 0; p <= P; ++p) {
      const float* m = p == 0 ? &c.means[k * c.dim] : &c.basis[(k * P + p - 1) * c.dim];
      for (int i = 0; i < no2; ++i) {
        double s[3] = {0, 0, 0};
        const double scale = p == 0 ? 1.0 : c.weightScales[k * P + p - 1];
        for (int j = 0; j < ni2; ++j)
          for (int ch = 0; ch < 3; ++ch) s[ch] += scale * double(m[i * ni2 + j]) * light[size_t(j) * 3 + ch];
        clusterLight.insert(clusterLight.end(), {float(s[0]), float(s[1]), float(s[2]), 1.0f});
      }
    }

  const int cases = 24;
  nlohmann::json d;
  std::vector<float> normal, view, alb, weights, lightF(light.begin(), light.end());
  std::vector<int> vertex, cluster, normalised;
  std::vector<double> expect;  // [row][case][rgb]
  std::vector<double> expectCpca;
  std::vector<float> rec(c.dim);
  for (int k = 0; k < cases; ++k) {
    const size_t v = size_t(k) * (scene.vertexCount() - 1) / (cases - 1);
    const double n[3] = {scene.normals[3 * v], scene.normals[3 * v + 1], scene.normals[3 * v + 2]};
    // A view direction in n's hemisphere, different per case.
    double w[3] = {n[0] + 0.5 * std::cos(k), n[1] + 0.5 * std::sin(k), n[2] + 0.3};
    const double wl = std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
    for (double& x : w) x /= wl;
    const double nv = n[0] * w[0] + n[1] * w[1] + n[2] * w[2];
    const std::array<double, 3> R{2 * nv * n[0] - w[0], 2 * nv * n[1] - w[1], 2 * nv * n[2] - w[2]};
    const double cosNR = n[0] * R[0] + n[1] * R[1] + n[2] * R[2];
    const bool norm = k % 2 == 0;
    vertex.push_back(int(v));
    cluster.push_back(c.clusterOf[v]);
    normalised.push_back(norm ? 1 : 0);
    for (int i = 0; i < 3; ++i) normal.push_back(float(n[i])), view.push_back(float(w[i])), alb.push_back(scene.albedo[3 * v + i]);
    for (size_t p = 0; p < P; ++p) {
      const float step = cpcaInt8Step(c, v, p);
      weights.push_back(float(cpcaInt8Code(c.weights[v * P + p], step)) * c.vertexScales[v]);
    }
    cpcaReconstruct(c, v, rec.data());
    for (int form = 0; form < 2; ++form) {
      const float* m = form == 0 ? r.vertex(v) : rec.data();
      for (int ch = 0; ch < 3; ++ch) {
        std::vector<double> t(size_t(no2), 0.0);
        for (int i = 0; i < no2; ++i)
          for (int j = 0; j < ni2; ++j) t[size_t(i)] += double(m[i * ni2 + j]) * light[size_t(j) * 3 + ch];
        (form == 0 ? expect : expectCpca).push_back(scene.albedo[3 * v + ch] * shadeGlossy(lobe, no, t.data(), R, norm, cosNR));
      }
    }
  }
  d["cases"] = cases, d["vectors"] = P, d["orderOut"] = no, d["orderIn"] = ni, d["nIn"] = ni2, d["nOut"] = no2;
  d["matrixRows"] = scene.vertexCount() * size_t(no2);
  d["matrices"] = r.matrices;
  d["clusterRows"] = K * (P + 1);
  d["clusterLight"] = clusterLight;
  d["light"] = lightF;
  d["lobe"] = std::vector<float>(lobe.g.begin(), lobe.g.end());
  d["normal"] = normal, d["view"] = view, d["albedo"] = alb, d["vertex"] = vertex, d["cluster"] = cluster;
  d["normalised"] = normalised, d["weights"] = weights;

  const std::string dir = test::tempDir("glossy_glsl");
  const std::string page = dir + "/page.html";
  {
    std::ofstream f(page);
    f << replaceAll(replaceAll(kPage, "__DATA__", d.dump()), "__GLSL__", nlohmann::json(readText(glslPath)).dump());
  }
  const test::CliResult res = test::chromiumPage(chromium, page);
  const size_t at = res.output.find("RESULT [");
  INFO("chromium exit " << res.exitCode << ": " << res.output.substr(0, 2000));
  REQUIRE(at != std::string::npos);
  std::vector<double> got;
  const char* p = res.output.c_str() + at + 8;
  while (*p && *p != ']') {
    char* end = nullptr;
    got.push_back(std::strtod(p, &end));
    p = end;
    if (*p == ',') ++p;
  }
  REQUIRE(got.size() == size_t(cases) * 2 * 4);
  double worst = 0, worstCpca = 0, largest = 0;
  for (int k = 0; k < cases; ++k)
    for (int ch = 0; ch < 3; ++ch) {
      const double g0 = got[(0 * cases + k) * 4 + ch], g1 = got[(size_t(cases) + k) * 4 + ch];
      const double e0 = expect[size_t(k) * 3 + ch], e1 = expectCpca[size_t(k) * 3 + ch];
      worst = std::max(worst, std::abs(g0 - e0) / (1 + std::abs(e0)));
      worstCpca = std::max(worstCpca, std::abs(g1 - e1) / (1 + std::abs(e1)));
      largest = std::max(largest, std::abs(e0));
    }
  INFO("GLSL vs prtbake: uncompressed " << worst << ", CPCA " << worstCpca << " (largest value " << largest << ")");
  CHECK(worst < kGlslTol);
  CHECK(worstCpca < kGlslTol);
  CHECK(largest > 0.1);  // the cases shade something
}
