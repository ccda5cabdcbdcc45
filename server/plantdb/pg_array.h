// PostgreSQL array literals, so that a batch of rows goes as one statement per table
// (INSERT ... SELECT FROM unnest($1::bigint[], ...)) instead of one round trip per row.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace rangex {

class PgArray {
 public:
  PgArray& add(const std::string& v);  // quoted, escaped
  PgArray& add(int64_t v);
  PgArray& add(double v);  // exactly (pg_exact)
  PgArray& add(bool v);
  std::string text() const { return "{" + body_ + "}"; }

 private:
  void sep() {
    if (!body_.empty()) body_ += ',';
  }
  std::string body_;
};

}  // namespace rangex
