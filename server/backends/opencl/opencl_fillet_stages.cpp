// The opencl backend's fillet stages (pseudo-X-ray map, IRLS sums) and dual-energy stages:
// their buffers, grown as needed, enqueued on queue 0.
#include <algorithm>
#include <cmath>
#include <vector>

#include "backends/opencl/opencl_backend.h"
#include "backends/opencl/opencl_backend_impl.h"

namespace rangex {

namespace {
constexpr size_t kFilletGroup = 256;  // work-items per fillet (a power of two: the reduction)
}  // namespace

// The fillet stages.

void OpenClBackend::Impl::ensure(Fillets& d, const FilletBatch& b) {
  const size_t n = std::max<size_t>(size_t(b.pixels()), 1);
  if (n > d.pixels) {
    d.thickness = buffer(n * 4, CL_MEM_READ_ONLY);
    d.xray = buffer(n * 2, CL_MEM_READ_ONLY);
    d.use = buffer(n, CL_MEM_READ_ONLY);
    for (cl::Buffer* x : {&d.ln_p, &d.p, &d.residual, &d.z}) *x = buffer(n * 4);
    d.r = buffer(n * 8);
    d.pixels = n;
  }
  if (b.fillets > d.fillets) {
    d.offsets = buffer(size_t(b.fillets + 1) * 4, CL_MEM_READ_ONLY);
    d.models = buffer(size_t(b.fillets) * sizeof(kernel::FilletModelK), CL_MEM_READ_ONLY);
    d.sums = buffer(size_t(b.fillets) * IRLS_SUMS * 8);
    d.fillets = b.fillets;
  }
  if (!t_ln_dn.mem()) {
    std::vector<double> ln(65536);
    for (size_t i = 0; i < ln.size(); ++i) ln[i] = std::log(double(i));
    t_ln_dn = buffer(ln.size() * 8, CL_MEM_READ_ONLY);
    cl::check(clEnqueueWriteBuffer(q(0), t_ln_dn.mem(), CL_TRUE, 0, ln.size() * 8, ln.data(), 0,
                                   nullptr, nullptr),
              "clEnqueueWriteBuffer (ln table)");
  }
}

// Uploads a batch of fillets' inputs.
void OpenClBackend::Impl::write_fillets(cl_command_queue qq, const FilletBatch& b,
                                        std::vector<cl_event>& up) {
  check_fillet_batch(b);
  ensure(fb, b);
  const size_t n = size_t(b.pixels());
  cl::write(qq, fb.thickness.mem(), b.thickness, n * 4, up);
  cl::write(qq, fb.xray.mem(), b.xray, n * 2, up);
  cl::write(qq, fb.use.mem(), b.use, n, up);
  cl::write(qq, fb.offsets.mem(), b.offsets, size_t(b.fillets + 1) * 4, up);
  cl::write(qq, fb.models.mem(), b.models, size_t(b.fillets) * sizeof(kernel::FilletModelK), up);
}

void OpenClBackend::Impl::check_guards(const Fillets& d, cl_command_queue qq) {
  if (!opt.guards) return;
  for (const cl::Buffer* x : d.all()) x->check_guards(qq, "fillets");
}

void OpenClBackend::pseudo_xray(const FilletBatch& b, float* ln_p, float* p, float* residual,
                                float* z) {
  Impl& m = *impl_;
  if (b.fillets == 0) return;
  const cl_command_queue qq = m.q(0);
  std::vector<cl_event> up, run, down;
  m.write_fillets(qq, b, up);
  Impl::Fillets& d = m.fb;
  cl::args(m.k_pseudo, d.thickness.mem(), d.xray.mem(), d.use.mem(), d.offsets.mem(),
           d.models.mem(), m.t_ln_dn.mem(), d.ln_p.mem(), d.p.mem(), d.residual.mem(), d.z.mem());
  cl::launch(qq, m.k_pseudo, size_t(b.fillets) * kFilletGroup, run, kFilletGroup);
  const size_t n = size_t(b.pixels());
  cl::read(qq, d.ln_p.mem(), ln_p, n * 4, down);
  cl::read(qq, d.p.mem(), p, n * 4, down);
  cl::read(qq, d.residual.mem(), residual, n * 4, down);
  cl::read(qq, d.z.mem(), z, n * 4, down);
  m.finish(qq);
  m.check_guards(d, qq);
  times_ = {cl::seconds(up), cl::seconds(run), cl::seconds(down)};
}

void OpenClBackend::irls_sums(const FilletBatch& b, double* r, double* sums) {
  Impl& m = *impl_;
  if (b.fillets == 0) return;
  const cl_command_queue qq = m.q(0);
  std::vector<cl_event> up, run, down;
  m.write_fillets(qq, b, up);
  Impl::Fillets& d = m.fb;
  cl::args(m.k_irls, d.thickness.mem(), d.xray.mem(), d.use.mem(), d.offsets.mem(), d.models.mem(),
           m.t_ln_dn.mem(), d.r.mem(), d.sums.mem());
  cl::check(clSetKernelArg(m.k_irls, 8, kFilletGroup * IRLS_SUMS * sizeof(double), nullptr),
            "clSetKernelArg (local sums)");
  cl::launch(qq, m.k_irls, size_t(b.fillets) * kFilletGroup, run, kFilletGroup);
  cl::read(qq, d.r.mem(), r, size_t(b.pixels()) * 8, down);
  cl::read(qq, d.sums.mem(), sums, size_t(b.fillets) * IRLS_SUMS * 8, down);
  m.finish(qq);
  m.check_guards(d, qq);
  times_ = {cl::seconds(up), cl::seconds(run), cl::seconds(down)};
}

// The dual-energy stages.

void OpenClBackend::Impl::ensure(Pixels& d, size_t pixels) {
  const size_t n = std::max<size_t>(pixels, 1);
  if (!d.params.mem()) d.params = buffer(sizeof(kernel::DualEnergyK), CL_MEM_READ_ONLY);
  if (n <= d.pixels) return;
  for (cl::Buffer* x : {&d.low, &d.high}) *x = buffer(n * 2, CL_MEM_READ_ONLY);
  for (cl::Buffer* x : {&d.open_low, &d.open_high, &d.thickness, &d.phi, &d.phi_var})
    *x = buffer(n * 4, CL_MEM_READ_ONLY);
  d.use = buffer(n, CL_MEM_READ_ONLY);
  d.basis = buffer(n * 20);
  d.lengths = buffer(n * 12);
  d.sigma = buffer(n * 12);
  d.bone = buffer(n * 4);
  d.bone_sigma = buffer(n * 4);
  d.pixels = n;
}

// A dual-energy batch's buffers, grown to `pixels`, with the parameters' upload enqueued.
OpenClBackend::Impl::Pixels& OpenClBackend::Impl::begin_pixels(cl_command_queue qq, int pixels,
                                                               const DualEnergyParams& k,
                                                               std::vector<cl_event>& up) {
  ensure(px, size_t(pixels));
  cl::write(qq, px.params.mem(), &k, sizeof k, up);
  return px;
}

void OpenClBackend::Impl::finish_pixels(cl_command_queue qq) {
  finish(qq);
  if (opt.guards)
    for (const cl::Buffer* x : px.all()) x->check_guards(qq, "dual energy");
}

void OpenClBackend::dual_energy(const DualEnergyBatch& b, const DualEnergyParams& k, float* basis,
                                float* lengths, float* sigma) {
  check_dual_energy_batch(b, k);
  if (b.pixels == 0) return;
  Impl& m = *impl_;
  const cl_command_queue qq = m.q(0);
  std::vector<cl_event> up, run, down;
  Impl::Pixels& d = m.begin_pixels(qq, b.pixels, k, up);
  const size_t n = size_t(b.pixels);
  const uint8_t* use = b.use;
  if (!use) {
    m.every_pixel.assign(n, 1);
    use = m.every_pixel.data();
  }
  cl::write(qq, d.low.mem(), b.low, n * 2, up);
  cl::write(qq, d.high.mem(), b.high, n * 2, up);
  cl::write(qq, d.open_low.mem(), b.open_low, n * 4, up);
  cl::write(qq, d.open_high.mem(), b.open_high, n * 4, up);
  cl::write(qq, d.thickness.mem(), b.thickness, n * 4, up);
  cl::write(qq, d.use.mem(), use, n, up);
  cl::args(m.k_dual, d.low.mem(), d.high.mem(), d.open_low.mem(), d.open_high.mem(),
           d.thickness.mem(), d.use.mem(), d.params.mem(), cl_int(b.pixels), d.basis.mem(),
           d.lengths.mem(), d.sigma.mem());
  cl::launch(qq, m.k_dual, n, run);
  cl::read(qq, d.basis.mem(), basis, n * 20, down);
  cl::read(qq, d.lengths.mem(), lengths, n * 12, down);
  cl::read(qq, d.sigma.mem(), sigma, n * 12, down);
  m.finish_pixels(qq);
  times_ = {cl::seconds(up), cl::seconds(run), cl::seconds(down)};
}

void OpenClBackend::dual_energy_bone(const DualEnergyBoneBatch& b, const DualEnergyParams& k,
                                     float* bone, float* bone_sigma) {
  check_dual_energy_batch(b, k);
  if (b.pixels == 0) return;
  Impl& m = *impl_;
  const cl_command_queue qq = m.q(0);
  std::vector<cl_event> up, run, down;
  Impl::Pixels& d = m.begin_pixels(qq, b.pixels, k, up);
  const size_t n = size_t(b.pixels);
  cl::write(qq, d.basis.mem(), b.basis, n * 20, up);
  cl::write(qq, d.thickness.mem(), b.thickness, n * 4, up);
  cl::write(qq, d.phi.mem(), b.phi, n * 4, up);
  cl::write(qq, d.phi_var.mem(), b.phi_var, n * 4, up);
  cl::args(m.k_bone, d.basis.mem(), d.thickness.mem(), d.phi.mem(), d.phi_var.mem(), d.params.mem(),
           cl_int(b.pixels), cl_double(b.density_var), d.bone.mem(), d.bone_sigma.mem());
  cl::launch(qq, m.k_bone, n, run);
  cl::read(qq, d.bone.mem(), bone, n * 4, down);
  cl::read(qq, d.bone_sigma.mem(), bone_sigma, n * 4, down);
  m.finish_pixels(qq);
  times_ = {cl::seconds(up), cl::seconds(run), cl::seconds(down)};
}

}  // namespace rangex
