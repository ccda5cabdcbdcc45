// Stage 2, rectification: one work-item per (frame, column), rectify()
// (server/pipeline/rectify_table.cpp): the bilinear lookup of the sub-pixel row in the
// frame's camera table, giving the laser-plane point (x, z) in mm.

kernel void rectify(global const float* row, global const int* valid, int count, int width,
                    global const int* frame_slot, global const struct RectTableK* tables,
                    global const float* nodes, global float* x, global float* z,
                    global int* out_valid) {
  const size_t o = get_global_id(0);
  if (o >= (size_t)count * width) return;
  const int fi = (int)(o / width), c = (int)(o % width);
  if (!valid[o]) {
    x[o] = z[o] = NAN;
    out_valid[o] = 0;
    return;
  }
  const struct RectTableK t = tables[frame_slot[fi]];
  const float inv = 1.0f / (float)t.step;
  const float gu = (float)c * inv, gv = row[o] * inv;
  const int i = min((int)gu, t.nu - 2);
  const int j = clamp((int)floor(gv), 0, t.nv - 2);
  const float fu = gu - (float)i, fv = gv - (float)j;
  global const float* tx = nodes + t.offset;
  global const float* tz = tx + t.nu * t.nv;
  const int n00 = j * t.nu + i, n10 = n00 + 1, n01 = n00 + t.nu, n11 = n01 + 1;
  const float w00 = (1 - fu) * (1 - fv), w10 = fu * (1 - fv), w01 = (1 - fu) * fv, w11 = fu * fv;
  x[o] = w00 * tx[n00] + w10 * tx[n10] + w01 * tx[n01] + w11 * tx[n11];
  z[o] = w00 * tz[n00] + w10 * tz[n10] + w01 * tz[n01] + w11 * tz[n11];
  out_valid[o] = 1;
}
