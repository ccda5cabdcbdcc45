// A zipped GenICam description as a device could serve it: whatever its bytes, the check
// (sensors/genicam_zip.h) refuses it, or Aravis's own unzip, the one rangexd would then run,
// reads only inside it and unzips at most the bound. The archive lies between two unreadable
// pages, so a read past either end faults (Aravis is not instrumented; the pages are what
// see its reads).
//
// Input: the archive's bytes (tests/fuzz/make_seeds.py writes the seeds).
#include <arv.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string_view>

#include "sensors/genicam_zip.h"

using namespace rangex;

namespace {
constexpr uint64_t kBound = uint64_t(4) << 20;  // smaller than the product's, to run fast
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view zip(reinterpret_cast<const char*>(data), size);
  if (size == 0 || !genicam_zip_refusal(zip, kBound).empty()) return 0;
  const size_t page = size_t(sysconf(_SC_PAGESIZE)), pages = (size + page - 1) / page;
  char* base = static_cast<char*>(mmap(nullptr, (pages + 2) * page, PROT_READ | PROT_WRITE,
                                       MAP_PRIVATE | MAP_ANONYMOUS, -1, 0));
  if (base == MAP_FAILED) abort();
  mprotect(base, page, PROT_NONE);
  mprotect(base + (pages + 1) * page, page, PROT_NONE);
  char* copy = base + (pages + 1) * page - size;
  std::memcpy(copy, data, size);
  ArvZip* a = arv_zip_new(copy, size);
  const GSList* files = arv_zip_get_file_list(a);
  size_t unzipped = 0;
  if (files)
    g_free(arv_zip_get_file(a, arv_zip_file_get_name(static_cast<ArvZipFile*>(files->data)),
                            &unzipped));
  arv_zip_free(a);
  munmap(base, (pages + 2) * page);
  if (unzipped > kBound) abort();  // the check took an archive that unzips past the bound
  return 0;
}
