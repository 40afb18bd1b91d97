// prt_glossy.glsl: run-time shading of prtbake's glossy PRT (docs/glossy.md), GLSL ES 3.00
// (WebGL 2) and GLSL 3.30+. The test tests/test_glossy_glsl.cpp runs these functions in
// headless Chromium and compares them with prtbake's own values.
//
// Conventions (docs/conventions.md "SH basis"): real orthonormal SH with the Condon–Shortley phase, index
// i = l(l+1)+m, evaluated on unit directions of the bake's world frame.
//
// Shading of a vertex (or pixel) with transfer matrix M (n_out² × n_in²), environment
// radiance coefficients l (n_in², RGB), a lobe with Funk–Hecke factors ĝ_l (prtbake
// prints and documents them: normalised Phong, GGX fit, cosine), the reflected view
// direction R = reflect(−V, n):
//   t = M l                                   (transferred radiance, n_out² RGB)
//   L = albedo · Σ_lm ĝ_l t_lm Y_lm(R) / D    (D = 1, or the horizon norm below)
// CPCA (prtbake cpca): M_v ≈ μ_k + Σ_p w_vp b_kp, k = cluster of v, so
//   t_v = U_k0 + Σ_p w_vp U_k(p+1),  U_k0 = μ_k l, U_k(p+1) = b_kp l,
// with U (K·(P+1) vectors of n_out² RGB) computed once per lighting by the application.
// int8 weights (--weights int8): w_vp = q_vp · c_kp · t_v; fold c_kp into U (U_k(p+1) =
// c_kp b_kp l) and pass w_p = q_vp · t_v (q from a BYTE vertex attribute, t_v a float one).
//
// Define PRT_ORDER_OUT (2..6) and PRT_ORDER_IN (2..6) before including this file, and
// PRT_CPCA_VECTORS (≥ P, default 128) to size the weight array.
#ifndef PRT_ORDER_OUT
#define PRT_ORDER_OUT 3
#endif
#ifndef PRT_ORDER_IN
#define PRT_ORDER_IN PRT_ORDER_OUT
#endif
#ifndef PRT_CPCA_VECTORS
#define PRT_CPCA_VECTORS 128
#endif
#define PRT_N_OUT (PRT_ORDER_OUT * PRT_ORDER_OUT)
#define PRT_N_IN (PRT_ORDER_IN * PRT_ORDER_IN)

// Y_i(d) for i < PRT_N_OUT, d a unit vector: the stable recurrence of the normalised
// associated Legendre functions (prtbake/sh.h), Q_l^m = K_l^m P_l^m / sin^m θ, with
// sin^m θ e^{imφ} = (x + iy)^m.
void prtShEval(vec3 d, out float y[PRT_N_OUT]) {
  float qmm = 0.28209479177387814;  // 1/√(4π)
  float cm = 1.0, sm = 0.0;
  for (int m = 0; m < PRT_ORDER_OUT; ++m) {
    if (m > 0) {
      qmm *= -sqrt((2.0 * float(m) + 1.0) / (2.0 * float(m)));
      float c = d.x * cm - d.y * sm;
      sm = d.x * sm + d.y * cm;
      cm = c;
    }
    float q2 = 0.0, q1 = qmm;
    for (int l = m; l < PRT_ORDER_OUT; ++l) {
      float q;
      if (l == m) {
        q = qmm;
      } else if (l == m + 1) {
        q = sqrt(2.0 * float(m) + 3.0) * d.z * qmm;
      } else {
        float fl = float(l), fm = float(m);
        float a = sqrt((4.0 * fl * fl - 1.0) / (fl * fl - fm * fm));
        float b = sqrt(((fl - 1.0) * (fl - 1.0) - fm * fm) / (4.0 * (fl - 1.0) * (fl - 1.0) - 1.0));
        q = a * (d.z * q1 - b * q2);
      }
      if (l > m) {
        q2 = q1;
        q1 = q;
      }
      if (m == 0) {
        y[l * (l + 1)] = q;
      } else {
        y[l * (l + 1) + m] = 1.4142135623730951 * q * cm;
        y[l * (l + 1) - m] = 1.4142135623730951 * q * sm;
      }
    }
  }
}

// Σ_lm ĝ_l t_lm Y_lm(R): the lobe about R applied to transferred radiance t (RGB).
vec3 prtGlossyLobe(vec3 t[PRT_N_OUT], float g[PRT_ORDER_OUT], vec3 R) {
  float y[PRT_N_OUT];
  prtShEval(R, y);
  vec3 s = vec3(0.0);
  for (int l = 0; l < PRT_ORDER_OUT; ++l)
    for (int i = l * l; i < (l + 1) * (l + 1); ++i) s += g[l] * t[i] * y[i];
  return s;
}

// The horizon norm D(n·R) = Σ_l ĝ_l ĥ_l (2l+1)/(4π) P_l(n·R), ĥ_l = 2π ∫_0^1 P_l: what the
// lobe returns from an unoccluded vertex under a white sky (ĥ = 2π, π, 0, −π/4, 0, π/8
// for l = 0..5). Dividing by it makes the white furnace show the albedo. (prtbake's
// preview interpolates the vertices' ĥ_l Y_lm(n) instead, which equals this at a vertex.)
float prtHorizonNorm(float g[PRT_ORDER_OUT], float cosNR) {
  const float h[6] = float[6](6.283185307179586, 3.141592653589793, 0.0, -0.7853981633974483, 0.0, 0.39269908169872414);
  float c = max(cosNR, 0.0);
  float p0 = 1.0, p1 = c, s = g[0] * h[0] * 0.07957747154594767;  // (2l+1)/(4π) at l = 0
  if (PRT_ORDER_OUT > 1) s += g[1] * h[1] * 3.0 * 0.07957747154594767 * p1;
  for (int l = 2; l < PRT_ORDER_OUT; ++l) {
    float fl = float(l);
    float p2 = ((2.0 * fl - 1.0) * c * p1 - (fl - 1.0) * p0) / fl;
    s += g[l] * h[l] * (2.0 * fl + 1.0) * 0.07957747154594767 * p2;
    p0 = p1;
    p1 = p2;
  }
  return max(s, 1e-3);
}

// Uncompressed: t_i = Σ_j M_ij l_j for one vertex, M read from a R32F texture holding
// PRT_N_IN columns and PRT_N_OUT rows per vertex (texel (j, v·PRT_N_OUT + i) = M_v[i][j],
// the .npy's row-major order; grey matrices, the usual case).
void prtTransfer(highp sampler2D matrices, int vertex, vec3 light[PRT_N_IN], out vec3 t[PRT_N_OUT]) {
  for (int i = 0; i < PRT_N_OUT; ++i) {
    vec3 s = vec3(0.0);
    for (int j = 0; j < PRT_N_IN; ++j) s += texelFetch(matrices, ivec2(j, vertex * PRT_N_OUT + i), 0).r * light[j];
    t[i] = s;
  }
}

// CPCA: t_i = U_k0,i + Σ_p w_p U_k(p+1),i, U read from a RGB32F texture holding PRT_N_OUT
// columns and one row per (cluster, vector) (texel (i, k·(P+1) + p) = U_kp,i, p = 0 the
// mean's), with P = vectors (≤ PRT_CPCA_VECTORS) and w the vertex's P weights.
void prtTransferCpca(highp sampler2D clusterLight, int cluster, int vectors, float w[PRT_CPCA_VECTORS],
                     out vec3 t[PRT_N_OUT]) {
  int row = cluster * (vectors + 1);
  for (int i = 0; i < PRT_N_OUT; ++i) {
    vec3 s = texelFetch(clusterLight, ivec2(i, row), 0).rgb;
    for (int p = 0; p < vectors; ++p) s += w[p] * texelFetch(clusterLight, ivec2(i, row + 1 + p), 0).rgb;
    t[i] = s;
  }
}

// The whole shading: albedo · lobe(t, R) / D(n·R) (normalised) or / 1.
vec3 prtGlossyShade(vec3 t[PRT_N_OUT], float g[PRT_ORDER_OUT], vec3 n, vec3 viewDir, vec3 albedo, bool normalised) {
  vec3 R = reflect(-viewDir, n);
  vec3 L = prtGlossyLobe(t, g, R);
  return albedo * (normalised ? L / prtHorizonNorm(g, dot(n, R)) : L);
}
