// splat_backward_math and its sums (splat_backward.hpp), included inside a namespace: once in
// fillgs::internal (double) and once per instruction set in splat_backward_simd.cpp, so that
// each copy is compiled for its target. No include guard, by design.

/// A 3-term sum of a small Eigen product (SSE2 packets of two doubles, the library's build):
/// sequential, (a0 + a1) + a2, where Eigen evaluates it on a packet (rows 0 and 1 of a
/// column-major result, every row of a result of two rows, a dot product of contiguous
/// vectors, a product with a transposed left factor); the tree a0 + (a1 + a2) of its scalar
/// reduction on row 2 of a three-row result.
template <typename V>
V sum3_seq(V a0, V a1, V a2) {
  return (a0 + a1) + a2;
}
template <typename V>
V sum3_row(int row, V a0, V a1, V a2) {
  return row < 2 ? (a0 + a1) + a2 : a0 + (a1 + a2);
}

/// Adds to gm, gs, gq (mean, scale, rotation) what project_splat_backward adds; *used says
/// where the projection is defined (p.z > near, det > 0), the only places it adds anything
/// (elsewhere the caller discards these values). `set` makes a V of a double.
template <typename V, typename M, typename S>
void splat_backward_math(const FrustumCamera& cam, const V mean[3], const V scale[3], const V rot[4], V dL_du, V dL_dv,
                         const V gconic[3], V gm[3], V gs[3], V gq[4], M* used, S set) {
  V W[3][3];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) W[r][c] = set(cam.W[r][c]);
  V p[3];
  for (int r = 0; r < 3; ++r) p[r] = sum3_row(r, W[r][0] * mean[0], W[r][1] * mean[1], W[r][2] * mean[2]) + set(cam.t[r]);
  const V zero = set(0.0), one = set(1.0), two = set(2.0);
  M ok = less(set(cam.near), p[2]);
  const V w = rot[0], x = rot[1], y = rot[2], z = rot[3];
  const V Rg[3][3] = {{one - two * (y * y + z * z), two * (x * y - w * z), two * (x * z + w * y)},
                      {two * (x * y + w * z), one - two * (x * x + z * z), two * (y * z - w * x)},
                      {two * (x * z - w * y), two * (y * z + w * x), one - two * (x * x + y * y)}};
  V Mm[3][3];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) Mm[r][c] = Rg[r][c] * scale[c];
  V cov3[3][3];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) cov3[r][c] = sum3_row(r, Mm[r][0] * Mm[c][0], Mm[r][1] * Mm[c][1], Mm[r][2] * Mm[c][2]);
  const V fx = set(cam.fx), fy = set(cam.fy), pz = p[2];
  const V limx = set(cam.limx), limy = set(cam.limy);
  const V rx = p[0] / pz, ry = p[1] / pz;
  const M clamp_x = either(less(rx, neg(limx)), less(limx, rx)), clamp_y = either(less(ry, neg(limy)), less(limy, ry));
  // std::clamp(v, lo, hi): lo where v < lo, else hi where hi < v, else v.
  auto clampv = [&](V v, V lo, V hi) { return pick(less(v, lo), lo, pick(less(hi, v), hi, v)); };
  const V tx = clampv(rx, neg(limx), limx) * pz, ty = clampv(ry, neg(limy), limy) * pz;
  const V J[2][3] = {{fx / pz, zero, neg(fx * tx) / (pz * pz)}, {zero, fy / pz, neg(fy * ty) / (pz * pz)}};
  V T[2][3];
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c) T[r][c] = sum3_seq(J[r][0] * W[0][c], J[r][1] * W[1][c], J[r][2] * W[2][c]);
  V TC[2][3];
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c) TC[r][c] = sum3_seq(T[r][0] * cov3[0][c], T[r][1] * cov3[1][c], T[r][2] * cov3[2][c]);
  const V dil = set(cam.dilation);
  const V a = sum3_seq(TC[0][0] * T[0][0], TC[0][1] * T[0][1], TC[0][2] * T[0][2]) + dil;
  const V b = sum3_seq(TC[0][0] * T[1][0], TC[0][1] * T[1][1], TC[0][2] * T[1][2]);
  const V c = sum3_seq(TC[1][0] * T[1][0], TC[1][1] * T[1][1], TC[1][2] * T[1][2]) + dil;
  const V det = a * c - b * b;
  ok = both(ok, less(zero, det));
  *used = ok;

  const V d2 = det * det;
  const V gA = gconic[0], gB = gconic[1], gC = gconic[2];
  const V ga = gA * (neg(c) * c / d2) + gB * (b * c / d2) + gC * (neg(b) * b / d2);
  const V gb = gA * (two * b * c / d2) + gB * (set(-1.0) / det - two * b * b / d2) + gC * (two * a * b / d2);
  const V gc = gA * (neg(b) * b / d2) + gB * (a * b / d2) + gC * (neg(a) * a / d2);
  const V half = set(0.5);
  const V G2[2][2] = {{ga, half * gb}, {half * gb, gc}};
  // G3 = Tᵀ G2 T: (Tᵀ G2) first, each a 2-term sum.
  V TG[3][2];
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 2; ++k) TG[r][k] = T[0][r] * G2[0][k] + T[1][r] * G2[1][k];
  V G3[3][3];
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) G3[r][k] = TG[r][0] * T[0][k] + TG[r][1] * T[1][k];
  // GT = ((2 G2) T) cov3, GJ = GT Wᵀ.
  V G2T[2][3];
  for (int r = 0; r < 2; ++r)
    for (int k = 0; k < 3; ++k) G2T[r][k] = (two * G2[r][0]) * T[0][k] + (two * G2[r][1]) * T[1][k];
  V GT[2][3];
  for (int r = 0; r < 2; ++r)
    for (int k = 0; k < 3; ++k) GT[r][k] = sum3_seq(G2T[r][0] * cov3[0][k], G2T[r][1] * cov3[1][k], G2T[r][2] * cov3[2][k]);
  V GJ[2][3];
  for (int r = 0; r < 2; ++r)
    for (int k = 0; k < 3; ++k) GJ[r][k] = sum3_seq(GT[r][0] * W[k][0], GT[r][1] * W[k][1], GT[r][2] * W[k][2]);

  V gp[3] = {zero, zero, zero};
  const V pz2 = pz * pz;
  gp[2] = gp[2] + (neg(fx) / pz2 * GJ[0][0] - fy / pz2 * GJ[1][1]);
  // x: clamped → z only; else x and z.
  const V zx_clamped = fx * (tx / pz) / pz2 * GJ[0][2];
  const V x_free = neg(fx) / pz2 * GJ[0][2];
  const V zx_free = two * fx * p[0] / (pz2 * pz) * GJ[0][2];
  gp[2] = pick(clamp_x, gp[2] + zx_clamped, gp[2] + zx_free);
  gp[0] = pick(clamp_x, gp[0], gp[0] + x_free);
  const V zy_clamped = fy * (ty / pz) / pz2 * GJ[1][2];
  const V y_free = neg(fy) / pz2 * GJ[1][2];
  const V zy_free = two * fy * p[1] / (pz2 * pz) * GJ[1][2];
  gp[2] = pick(clamp_y, gp[2] + zy_clamped, gp[2] + zy_free);
  gp[1] = pick(clamp_y, gp[1], gp[1] + y_free);
  gp[0] = gp[0] + fx / pz * dL_du;
  gp[1] = gp[1] + fy / pz * dL_dv;
  gp[2] = gp[2] + (neg(fx) * p[0] / pz2 * dL_du - fy * p[1] / pz2 * dL_dv);
  for (int k = 0; k < 3; ++k) gm[k] = gm[k] + sum3_seq(W[0][k] * gp[0], W[1][k] * gp[1], W[2][k] * gp[2]);

  // Σ3 = M Mᵀ, M = R S: GM = (2 G3) M.
  V GM[3][3];
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) GM[r][k] = sum3_row(r, (two * G3[r][0]) * Mm[0][k], (two * G3[r][1]) * Mm[1][k], (two * G3[r][2]) * Mm[2][k]);
  for (int k = 0; k < 3; ++k) gs[k] = gs[k] + sum3_seq(Rg[0][k] * GM[0][k], Rg[1][k] * GM[1][k], Rg[2][k] * GM[2][k]);
  V G[3][3];
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) G[r][k] = GM[r][k] * scale[k];
  gq[0] = gq[0] + two * (neg(z) * G[0][1] + y * G[0][2] + z * G[1][0] - x * G[1][2] - y * G[2][0] + x * G[2][1]);
  gq[1] = gq[1] + two * (y * G[0][1] + z * G[0][2] + y * G[1][0] - two * x * G[1][1] - w * G[1][2] + z * G[2][0] + w * G[2][1] -
                         two * x * G[2][2]);
  gq[2] = gq[2] + two * (set(-2.0) * y * G[0][0] + x * G[0][1] + w * G[0][2] + x * G[1][0] + z * G[1][2] - w * G[2][0] +
                         z * G[2][1] - two * y * G[2][2]);
  gq[3] = gq[3] + two * (set(-2.0) * z * G[0][0] - w * G[0][1] + x * G[0][2] + w * G[1][0] - two * z * G[1][1] + y * G[1][2] +
                         x * G[2][0] + y * G[2][1]);
}

