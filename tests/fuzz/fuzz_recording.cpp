// A recording folder as it might arrive from a disk that filled, a copy cut short or a hand
// edit: recording.yaml and lane 0's four arrays, each from the input. The reader must refuse
// what does not add up with rangex::Error; what it accepts must read back line by line
// within the files (AddressSanitizer watches the mapped frames and the buffers).
//
// Input: five strings in FuzzedDataProvider's random-length encoding (a backslash doubles
// itself; a backslash then another byte ends the string): recording.yaml, cam0.u8,
// cam1.u8, xray.u16, encoder.i64 (tests/fuzz/make_seeds.py writes the seeds).
#include <fuzzer/FuzzedDataProvider.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <vector>

#include "core/error.h"
#include "core/recording.h"

using namespace rangex;
namespace fs = std::filesystem;

namespace {
// Removed when the fuzzer exits (a run of -runs=N ends with exit(): static destructors run).
struct Scratch {
  fs::path dir = fs::temp_directory_path() / ("rangex-fuzz-rec-" + std::to_string(getpid()));
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};
const fs::path& scratch() {
  static const Scratch s;
  return s.dir;
}
void write(const fs::path& p, const std::string& bytes) {
  std::ofstream(p, std::ios::binary | std::ios::trunc)
      .write(bytes.data(), std::streamsize(bytes.size()));
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  FuzzedDataProvider in(data, size);
  const fs::path dir = scratch();
  fs::remove_all(dir);
  fs::create_directories(dir / "lane0");
  write(dir / "recording.yaml", in.ConsumeRandomLengthString(4096));
  for (const char* f : {"cam0.u8", "cam1.u8", "xray.u16", "encoder.i64"})
    write(dir / "lane0" / f, in.ConsumeRandomLengthString(1 << 16));
  try {
    const RecordingReader rec(dir.string());
    const RecordingInfo& info = rec.info();
    const size_t frame = size_t(info.width) * size_t(info.height);
    // Lines a fuzzer can make are small; a header claiming huge frames was checked against
    // the files' sizes already, and reading it all would only be slow.
    if (frame * size_t(info.lines) > (size_t(1) << 22)) return 0;
    std::vector<uint8_t> c0(frame), c1(frame);
    std::vector<uint16_t> x(size_t(info.xray_pixels));
    int64_t e = 0;
    for (int lane : info.lanes) {
      for (int64_t n = 0; n < info.lines; ++n)
        rec.read(lane, n, 1, c0.data(), c1.data(), x.data(), &e);
      const auto m = rec.map_frames(lane);
      volatile uint8_t sum = 0;
      for (int64_t n = 0; n < info.lines; ++n)
        for (int c = 0; c < 2; ++c) sum = sum + m.frame(c, n)[frame - 1];
    }
  } catch (const Error&) {
  }
  return 0;
}
