// A description a device names NAME.zip is walked with every read bounded before Aravis
// unzips it: Aravis 0.8.26 trusts the archive's offsets and sizes (genicam_zip.h). What the
// check takes, Aravis's own unzip reads inside the archive.
#include <arv.h>
#include <gtest/gtest.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "sensors/fake_devices.h"
#include "sensors/genicam_zip.h"
#include "zip_archive.h"

using namespace rangex;
using namespace rangex::test;

namespace {

// `bytes` ending where an unreadable page begins, with one before them too: Aravis reading
// past either end of the archive faults instead of reading what happens to lie there.
class GuardedBytes {
 public:
  explicit GuardedBytes(const std::string& bytes) {
    const size_t page = size_t(sysconf(_SC_PAGESIZE));
    const size_t pages = (bytes.size() + page - 1) / page;
    size_ = (pages + 2) * page;
    base_ = static_cast<char*>(
        mmap(nullptr, size_, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0));
    mprotect(base_, page, PROT_NONE);
    mprotect(base_ + (pages + 1) * page, page, PROT_NONE);
    data_ = base_ + (pages + 1) * page - bytes.size();
    std::memcpy(data_, bytes.data(), bytes.size());
  }
  ~GuardedBytes() { munmap(base_, size_); }
  const char* data() const { return data_; }

 private:
  char *base_ = nullptr, *data_ = nullptr;
  size_t size_ = 0;
};

// Aravis's unzip as its GigE device runs it (the first file it lists), in a child process:
// 0 when it unzipped at most `max` bytes, 3 when more, -SIGNAL when it crashed.
int aravis_unzip_status(const std::string& zip, uint64_t max) {
  const pid_t pid = fork();
  if (pid == 0) {
    const GuardedBytes g(zip);
    ArvZip* a = arv_zip_new(g.data(), zip.size());
    const GSList* files = arv_zip_get_file_list(a);
    size_t size = 0;
    if (files) {
      void* out =
          arv_zip_get_file(a, arv_zip_file_get_name(static_cast<ArvZipFile*>(files->data)), &size);
      g_free(out);
    }
    arv_zip_free(a);
    _exit(size > max ? 3 : 0);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -WTERMSIG(status);
}

// What Aravis unzips from an archive the check took.
std::string aravis_unzip(const std::string& zip) {
  ArvZip* a = arv_zip_new(zip.data(), zip.size());
  const GSList* files = arv_zip_get_file_list(a);
  std::string out;
  if (files) {
    size_t size = 0;
    void* p =
        arv_zip_get_file(a, arv_zip_file_get_name(static_cast<ArvZipFile*>(files->data)), &size);
    out.assign(static_cast<const char*>(p), size);
    g_free(p);
  }
  arv_zip_free(a);
  return out;
}

}  // namespace

TEST(GenicamZip, ArchivesAsDevicesShipThemAreTakenAndUnzipWhole) {
  const std::string xml = FakeDevice::genicam_xml();
  for (const bool deflated : {true, false}) {
    const std::string zip = zip_archive("arv-fake-camera.xml", xml, deflated);
    EXPECT_EQ(genicam_zip_refusal(zip), "") << deflated;
    EXPECT_EQ(aravis_unzip(zip), xml) << deflated;
    // Bytes before the archive (a self-extractor's) move every offset alike.
    EXPECT_EQ(genicam_zip_refusal(std::string(100, 'x') + zip), "") << deflated;
  }
  EXPECT_TRUE(genicam_is_zip("Basler_acA2040.zip"));
  EXPECT_FALSE(genicam_is_zip("arv-fake-camera.xml"));
  EXPECT_FALSE(genicam_is_zip("desc.ZIP"));  // Aravis unzips by the exact suffix
}

TEST(GenicamZip, AnArchiveThatLiesIsRefusedNamingWhat) {
  const std::string xml = FakeDevice::genicam_xml();
  ZipLayout l;
  const std::string good = zip_archive("desc.xml", xml, true, &l);
  const size_t packed = l.entry - l.data;
  struct Lie {
    size_t at;
    uint64_t value;
    int bytes;
    std::string why;
  };
  const std::vector<Lie> lies = {
      // A bomb: 3 GiB declared is 3 GiB allocated and inflated into.
      {l.entry + 24, 0xC0000000u, 4,
       "'desc.xml' unzips to 3221225472 bytes, more than the 67108864"},
      {l.entry + 24, 0, 4, "'desc.xml' is empty"},
      {l.entry + 42, 0x7FFFFFFFu, 4, "'desc.xml' has no header where the directory says"},
      {l.entry + 20, packed + 4096, 4,
       "'desc.xml' has " + std::to_string(packed + 4096) + " bytes at"},
      // Stored: Aravis copies the declared size from where the data starts.
      {l.entry + 20, 60u << 20, 4, "has 62914560 bytes at"},
      {l.entry + 28, 0xFFFF, 2, "entry 1 has a name past its end"},
      {l.end + 16, 0xFFFFFF00u, 4,
       "the archive's directory (54 bytes at 4294967040) overlaps its end"},
      {l.end + 8, 2, 2, "the archive lists no file"},
      {l.entry, 0x12345678, 4, "the archive's directory holds no entry"},
  };
  for (const Lie& lie : lies) {
    std::string zip = good;
    zip_put(zip, lie.at, lie.value, lie.bytes);
    if (lie.at == l.entry + 20 && lie.value == (60u << 20))
      zip_put(zip, l.entry + 24, 60u << 20, 4);
    const std::string why = genicam_zip_refusal(zip);
    EXPECT_NE(why.find(lie.why), std::string::npos) << "wanted: " << lie.why << "\ngot: " << why;
  }
  EXPECT_EQ(genicam_zip_refusal(good.substr(0, good.size() - 22)),
            "the archive has no end of its central directory");
  EXPECT_EQ(genicam_zip_refusal(good.substr(0, good.size() - 10)),
            "the archive's end of directory is cut short");
  EXPECT_EQ(genicam_zip_refusal(""), "the archive has no end of its central directory");
  EXPECT_NE(genicam_zip_refusal(good, xml.size() - 1).find("more than the"), std::string::npos);
}

// Archives changed at random where the headers lie, and cut short: of what the check takes,
// Aravis's own unzip reads nothing outside the archive (a guard page each side would fault)
// and unzips at most the bound.
TEST(GenicamZip, WhatTheCheckTakesAravisUnzipsInsideTheArchive) {
  const std::string xml = FakeDevice::genicam_xml();
  ZipLayout l;
  const std::string good = zip_archive("desc.xml", xml, true, &l);
  std::vector<std::pair<size_t, size_t>> headers = {{0, 30}, {l.entry, 46}, {l.end, 22}};
  std::mt19937_64 rng(20261208);
  const uint64_t max = uint64_t(1) << 20;
  int taken = 0, refused = 0;
  for (int k = 0; k < 3000; ++k) {
    std::string zip = good;
    const auto [from, bytes] = headers[rng() % headers.size()];
    const size_t at = from + (rng() % (bytes - 1));
    switch (rng() % 4) {
      case 0:
        zip[at] = char(rng());
        break;
      case 1:
        zip_put(zip, at, rng() % (2 * zip.size()), 2);
        break;
      case 2:
        zip_put(zip, std::min(at, zip.size() - 4), uint32_t(rng()), 4);
        break;
      default:
        zip.resize(rng() % zip.size());
        break;
    }
    if (!genicam_zip_refusal(zip, max).empty()) {
      ++refused;
      continue;
    }
    ++taken;
    ASSERT_EQ(aravis_unzip_status(zip, max), 0) << "case " << k << " taken, Aravis failed on it";
  }
  EXPECT_GT(taken, 300);
  EXPECT_GT(refused, 300);
  std::printf("taken %d, refused %d of 3000\n", taken, refused);
}
