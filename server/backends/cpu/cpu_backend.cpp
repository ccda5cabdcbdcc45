#include "backends/cpu/cpu_backend.h"

#include <chrono>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <thread>

#include "core/error.h"

namespace rangex {

namespace {
double since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

// Staging is plain memory: the CPU reads the frames where the engine wrote them. A submitted
// batch computes on its slot's worker, so that the caller can fill the next batch, or decide
// the fillets of the last one, meanwhile. The worker is started once with the slot: a thread
// for each batch cost its creation and its stack on every batch (about 1,400 threads over one
// of the concurrency tests, and under ThreadSanitizer each stack's shadow as well).
class CpuBackend::Slot final : public LineBatchSlot {
 public:
  Slot() : worker_([this] { work(); }) {}
  // A batch never collected (its backend failed and was set aside) may still be computing
  // into this slot's memory: the worker finishes it before any member goes.
  ~Slot() override {
    {
      std::lock_guard<std::mutex> lock(mu_);
      stop_ = true;
    }
    cv_.notify_all();
    worker_.join();
  }
  void reserve(int lines, size_t frame_bytes) {
    if (lines <= capacity_) return;
    frames_buf_.resize(size_t(lines) * 2 * frame_bytes);
    lanes_buf_.resize(size_t(lines));
    frames_ = frames_buf_.data();
    lane_slot_ = lanes_buf_.data();
    capacity_ = lines;
  }
  void start(const LinePipeline& p) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      pipe_ = &p;
      state_ = State::queued;
    }
    cv_.notify_all();
  }
  // Seconds of the batch's stages, once they are done; rethrows what they threw.
  double finish() {
    std::unique_lock<std::mutex> lock(mu_);
    if (state_ == State::idle) fail("backend cpu: a batch was collected that was not submitted");
    cv_.wait(lock, [&] { return state_ == State::done; });
    state_ = State::idle;
    if (error_) std::rethrow_exception(error_);
    return seconds_;
  }
  bool busy = false;
  LineResults results;

 private:
  enum class State { idle, queued, done };  // queued until the worker has computed it
  void work() {
    std::unique_lock<std::mutex> lock(mu_);
    for (;;) {
      cv_.wait(lock, [&] { return stop_ || state_ == State::queued; });
      if (state_ != State::queued) return;  // stopped with nothing left to compute
      const LinePipeline& p = *pipe_;
      lock.unlock();
      std::exception_ptr error;
      const auto t0 = std::chrono::steady_clock::now();
      try {
        p.run(frames(), lines, lane_slot(), results);
      } catch (...) {
        error = std::current_exception();
      }
      const double seconds = since(t0);
      lock.lock();
      error_ = error;
      seconds_ = seconds;
      state_ = State::done;
      cv_.notify_all();
    }
  }
  std::vector<uint8_t> frames_buf_;
  std::vector<int32_t> lanes_buf_;
  std::mutex mu_;
  std::condition_variable cv_;
  State state_ = State::idle;
  bool stop_ = false;
  const LinePipeline* pipe_ = nullptr;
  std::exception_ptr error_;
  double seconds_ = 0;
  std::thread worker_;  // last: it starts once every member it reads is built
};

CpuBackend::CpuBackend(int threads, bool portable)
    : threads_(std::max(1, threads)), portable_(portable) {
  info_.name = portable ? "cpu-portable" : "cpu";
  info_.reference = !portable;
  info_.overlaps = true;
  info_.device = std::string("host CPU, ") +
                 (portable ? "portable groups of 16 columns" : stripe_vector_path());
  info_.driver = "rangex";
  info_.limits = std::to_string(threads_) + " stripe threads of " +
                 std::to_string(std::max(1u, std::thread::hardware_concurrency())) + " cores";
  for (auto& s : slots_) s = std::make_unique<Slot>();
}

CpuBackend::~CpuBackend() = default;

const LinePipeline& CpuBackend::pipe() const {
  if (!pipe_) fail("backend cpu: no lanes set");
  return *pipe_;
}

void CpuBackend::set_lanes(const std::vector<LaneConfig>& lanes) {
  pipe_ = std::make_unique<LinePipeline>(lanes, threads_, !portable_);
  lanes_ = lanes;
}

void CpuBackend::update_lane(int slot, const LaneConfig& lane) {
  if (!pipe_) fail("backend cpu: no lanes set");
  pipe_->update_lane(slot, lane);
  lanes_.at(slot) = lane;
}

LineBatchSlot& CpuBackend::acquire(int lines) {
  // The free slot (batches may be collected in any order).
  if (slots_[next_]->busy) next_ = 1 - next_;
  Slot& s = *slots_[next_];
  if (s.busy) fail("backend cpu: both staging slots are in flight; collect one first");
  next_ = 1 - next_;
  s.reserve(lines, size_t(pipe().width()) * pipe().height());
  s.lines = lines;
  s.busy = true;
  return s;
}

void CpuBackend::submit(LineBatchSlot& batch) {
  static_cast<Slot&>(batch).start(pipe());
}

void CpuBackend::collect(LineBatchSlot& batch, LineResults& out) {
  Slot& s = static_cast<Slot&>(batch);
  s.busy = false;
  times_ = {0, s.finish(), 0};  // rethrows what the stages threw
  std::swap(out, s.results);
}

void CpuBackend::stripes(const uint8_t* frames, int count, const int* frame_slot,
                         StripeOutput& out) {
  const auto t0 = std::chrono::steady_clock::now();
  pipe().stripes(frames, count, frame_slot, out);
  times_ = {0, since(t0), 0};
}

void CpuBackend::rectify(const float* row, const uint8_t* valid, int count, const int* frame_slot,
                         float* x, float* z, uint8_t* out_valid) {
  const auto t0 = std::chrono::steady_clock::now();
  pipe().rectify_rows(row, valid, count, frame_slot, x, z, out_valid);
  times_ = {0, since(t0), 0};
}

void CpuBackend::fuse(const float* x, const float* z, const uint8_t* valid, int lines,
                      const int* lane_slot, float* profile, uint8_t* profile_valid,
                      FusionStats* stats) {
  const auto t0 = std::chrono::steady_clock::now();
  pipe().fuse(x, z, valid, lines, lane_slot, profile, profile_valid, stats);
  times_ = {0, since(t0), 0};
}

void CpuBackend::project(const float* profile, const uint8_t* profile_valid, int lines,
                         const int* lane_slot, float* thickness, uint8_t* thickness_valid) {
  const auto t0 = std::chrono::steady_clock::now();
  pipe().project(profile, profile_valid, lines, lane_slot, thickness, thickness_valid);
  times_ = {0, since(t0), 0};
}

void CpuBackend::pseudo_xray(const FilletBatch& b, float* ln_p, float* p, float* residual,
                             float* z) {
  const auto t0 = std::chrono::steady_clock::now();
  pseudo_xray_map(b, ln_p, p, residual, z);
  times_ = {0, since(t0), 0};
}

void CpuBackend::irls_sums(const FilletBatch& b, double* r, double* sums) {
  const auto t0 = std::chrono::steady_clock::now();
  rangex::irls_sums(b, r, sums);
  times_ = {0, since(t0), 0};
}

void CpuBackend::dual_energy(const DualEnergyBatch& b, const DualEnergyParams& k, float* basis,
                             float* lengths, float* sigma) {
  check_dual_energy_batch(b, k);
  const auto t0 = std::chrono::steady_clock::now();
  dual_energy_basis(b, k, basis);
  dual_energy_lengths(basis, b.thickness, b.pixels, k, lengths, sigma);
  times_ = {0, since(t0), 0};
}

void CpuBackend::dual_energy_bone(const DualEnergyBoneBatch& b, const DualEnergyParams& k,
                                  float* bone, float* bone_sigma) {
  check_dual_energy_batch(b, k);
  const auto t0 = std::chrono::steady_clock::now();
  rangex::dual_energy_bone(b.basis, b.thickness, b.phi, b.phi_var, b.pixels, k, bone, bone_sigma,
                           b.density_var);
  times_ = {0, since(t0), 0};
}

}  // namespace rangex
