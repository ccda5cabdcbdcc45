// A file mapped read-only into memory: a recording's frames are copied once, from the page
// cache straight into the backend's staging, instead of read() into a buffer first.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>

namespace rangex {

class MappedFile {
 public:
  // Throws Error naming the file when it cannot be opened or mapped.
  explicit MappedFile(const std::string& path);
  ~MappedFile();
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  const uint8_t* data() const { return data_; }
  size_t size() const { return size_; }
  // The kernel reads ahead sequentially and drops what was read (a recording is streamed once).
  void advise_sequential() const;

 private:
  const uint8_t* data_ = nullptr;
  size_t size_ = 0;
};

}  // namespace rangex
