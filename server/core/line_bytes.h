// The bytes of one frame of a line: owned (moved out of a gRPC message, or rendered) or lent
// by a sensor's receive buffer, which `keep` holds until the line has been staged, so that a
// GigE Vision frame reaches the backend's staging without a copy of its own.
#pragma once
#include <cstddef>
#include <memory>
#include <string>
#include <utility>

namespace rangex {

class LineBytes {
 public:
  LineBytes() = default;
  LineBytes(std::string s) : own_(std::move(s)) {}  // NOLINT: a string is the owned case
  LineBytes& operator=(std::string s) {
    own_ = std::move(s);
    lent_ = nullptr;
    lent_size_ = 0;
    keep_.reset();
    return *this;
  }
  // `size` bytes at `data`, valid while `keep` lives.
  static LineBytes lent(char* data, size_t size, std::shared_ptr<void> keep) {
    LineBytes b;
    b.lent_ = data;
    b.lent_size_ = size;
    b.keep_ = std::move(keep);
    return b;
  }
  bool is_lent() const { return lent_ != nullptr; }
  const char* data() const { return lent_ ? lent_ : own_.data(); }
  char* data() { return lent_ ? lent_ : own_.data(); }
  size_t size() const { return lent_ ? lent_size_ : own_.size(); }
  bool empty() const { return size() == 0; }
  // Owned bytes of this size (a lent buffer is given back).
  void resize(size_t n) {
    take_ownership();
    own_.resize(n);
  }
  void assign(const char* p, size_t n) { *this = std::string(p, n); }
  // The first n bytes only (a lent buffer stays lent).
  void truncate(size_t n) {
    if (lent_)
      lent_size_ = n < lent_size_ ? n : lent_size_;
    else if (n < own_.size())
      own_.resize(n);
  }
  void assign(size_t n, char c) { *this = std::string(n, c); }

 private:
  void take_ownership() {
    if (!lent_) return;
    own_.assign(lent_, lent_size_);
    lent_ = nullptr;
    lent_size_ = 0;
    keep_.reset();
  }
  std::string own_;
  char* lent_ = nullptr;
  size_t lent_size_ = 0;
  std::shared_ptr<void> keep_;
};

}  // namespace rangex
