// Two-column numeric CSV with a header (e.g. "T,lnI"), as `rangexctl fit` reads it.
#pragma once
#include <string>
#include <vector>

namespace rangex {

struct CsvColumns {
  std::string x_name, y_name;
  std::vector<double> x, y;
};

// Throws Error naming the file, line and column of anything that is not two numbers per row;
// an empty table (header only) is refused too.
CsvColumns read_two_column_csv(const std::string& path);

}  // namespace rangex
