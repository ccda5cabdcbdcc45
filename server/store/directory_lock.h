// One writer per store: an exclusive lock on <dir>/rangexd.lock, held while the Store lives.
// Without it a second rangexd given the same data directory (another port, a hand-started
// copy beside the service) started, removed the first's staged images and would have written
// its own fillets and record chain into the same database. The lock is the kernel's (flock): it
// goes with the process, however it ends, so a crash leaves nothing to clean up.
#pragma once
#include <string>

namespace rangex {

class DirectoryLock {
 public:
  // Creates `dir` when it is missing. Throws Error naming the directory and the holder's pid
  // when another holds it.
  explicit DirectoryLock(const std::string& dir);
  ~DirectoryLock();
  DirectoryLock(const DirectoryLock&) = delete;
  DirectoryLock& operator=(const DirectoryLock&) = delete;

 private:
  int fd_ = -1;
};

}  // namespace rangex
