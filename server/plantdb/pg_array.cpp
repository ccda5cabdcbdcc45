#include "plantdb/pg_array.h"

#include "plantdb/pg_connection.h"

namespace rangex {

PgArray& PgArray::add(const std::string& v) {
  sep();
  body_ += '"';
  for (char c : v) {
    if (c == '"' || c == '\\') body_ += '\\';
    body_ += c;
  }
  body_ += '"';
  return *this;
}
PgArray& PgArray::add(int64_t v) {
  sep();
  body_ += std::to_string(v);
  return *this;
}
PgArray& PgArray::add(double v) {
  sep();
  body_ += pg_exact(v);
  return *this;
}
PgArray& PgArray::add(bool v) {
  sep();
  body_ += v ? "t" : "f";
  return *this;
}

}  // namespace rangex
