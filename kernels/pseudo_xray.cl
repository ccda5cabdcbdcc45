// The pseudo-X-ray stages for a batch of fillets: server/pipeline/pseudo_xray.cpp line by
// line. One work-group per fillet walks its pixels with a stride of the group size; the IRLS
// sums are reduced in the group (a tree in local memory, in double).
//   thickness, xray, use: per pixel; offsets: fillets + 1; models: per fillet;
//   ln_table[I] = ln(I) in double, as the host computes it.

kernel void pseudo_xray(global const float* thickness, global const ushort* xray,
                        global const uchar* use, global const int* offsets,
                        global const struct FilletModelK* models, global const double* ln_table,
                        global float* ln_p, global float* p, global float* residual,
                        global float* z) {
  const int f = (int)get_group_id(0);
  const struct FilletModelK m = models[f];
  const bool noise = m.noise_a > 0 || m.noise_b > 0;
  for (int i = offsets[f] + (int)get_local_id(0); i < offsets[f + 1]; i += (int)get_local_size(0)) {
    if (!use[i]) {
      ln_p[i] = p[i] = residual[i] = z[i] = NAN;
      continue;
    }
    const float lp = (float)(m.b0 + m.b1 * (double)thickness[i]);
    const float pp = exp(lp);
    const float r = (float)(ln_table[xray[i]] - (double)lp);
    ln_p[i] = lp;
    p[i] = pp;
    residual[i] = r;
    if (noise) {
      const double I = pp, v = m.noise_a / I + m.noise_b / (I * I);
      z[i] = (float)((double)r / sqrt(max(v, 1e-12)));
    } else {
      z[i] = NAN;
    }
  }
}

kernel void irls_sums(global const float* thickness, global const ushort* xray,
                      global const uchar* use, global const int* offsets,
                      global const struct FilletModelK* models, global const double* ln_table,
                      global double* r, global double* sums, local double* part) {
  const int f = (int)get_group_id(0), lid = (int)get_local_id(0), ls = (int)get_local_size(0);
  const struct FilletModelK m = models[f];
  double s[IRLS_SUMS] = {0, 0, 0, 0, 0, 0};
  for (int i = offsets[f] + lid; i < offsets[f + 1]; i += ls) {
    if (!use[i]) {
      r[i] = NAN;
      continue;
    }
    const double x = thickness[i], y = ln_table[xray[i]];
    const double ri = y - (m.b0 + m.b1 * x);
    double w = 1;
    if (m.scale > 0) {
      const double u = ri / m.scale / m.c;
      w = fabs(u) <= 1 ? (1 - u * u) * (1 - u * u) : 0.0;
    }
    r[i] = ri;
    s[0] += w;
    s[1] += w * x;
    s[2] += w * y;
    s[3] += w * x * x;
    s[4] += w * x * y;
    s[5] += w * ri * ri;
  }
  for (int k = 0; k < IRLS_SUMS; ++k) part[lid * IRLS_SUMS + k] = s[k];
  barrier(CLK_LOCAL_MEM_FENCE);
  for (int span = ls / 2; span > 0; span /= 2) {
    if (lid < span)
      for (int k = 0; k < IRLS_SUMS; ++k)
        part[lid * IRLS_SUMS + k] += part[(lid + span) * IRLS_SUMS + k];
    barrier(CLK_LOCAL_MEM_FENCE);
  }
  if (lid == 0)
    for (int k = 0; k < IRLS_SUMS; ++k) sums[f * IRLS_SUMS + k] = part[k];
}
