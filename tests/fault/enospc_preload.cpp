// A full disk, injected from outside the process: loaded with LD_PRELOAD into rangexd by
// tests/python/full_disk_test.py, it fails every write to a regular file with ENOSPC while
// the file named by RANGEX_DISK_FULL_FLAG exists, as a full store volume would (SQLite's
// pwrite, libpng's fwrite). Pipes, sockets and event descriptors are left alone, so gRPC
// runs on. Removing the flag file is freeing space.
#include <dlfcn.h>
#include <sys/stat.h>
#include <sys/uio.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>

namespace {

bool full(int fd) {
  const char* flag = std::getenv("RANGEX_DISK_FULL_FLAG");
  if (!flag || access(flag, F_OK) != 0) return false;
  struct stat st;
  return fstat(fd, &st) == 0 && S_ISREG(st.st_mode);
}

template <class F>
F real(const char* name) {
  return reinterpret_cast<F>(dlsym(RTLD_NEXT, name));
}

}  // namespace

extern "C" {

ssize_t write(int fd, const void* buf, size_t n) {
  static auto next = real<ssize_t (*)(int, const void*, size_t)>("write");
  if (full(fd)) return errno = ENOSPC, -1;
  return next(fd, buf, n);
}

ssize_t pwrite(int fd, const void* buf, size_t n, off_t at) {
  static auto next = real<ssize_t (*)(int, const void*, size_t, off_t)>("pwrite");
  if (full(fd)) return errno = ENOSPC, -1;
  return next(fd, buf, n, at);
}

ssize_t pwrite64(int fd, const void* buf, size_t n, off64_t at) {
  static auto next = real<ssize_t (*)(int, const void*, size_t, off64_t)>("pwrite64");
  if (full(fd)) return errno = ENOSPC, -1;
  return next(fd, buf, n, at);
}

ssize_t writev(int fd, const struct iovec* iov, int count) {
  static auto next = real<ssize_t (*)(int, const struct iovec*, int)>("writev");
  if (full(fd)) return errno = ENOSPC, -1;
  return next(fd, iov, count);
}

size_t fwrite(const void* buf, size_t size, size_t n, FILE* f) {
  static auto next = real<size_t (*)(const void*, size_t, size_t, FILE*)>("fwrite");
  if (full(fileno(f))) return errno = ENOSPC, 0;
  return next(buf, size, n, f);
}

}  // extern "C"
