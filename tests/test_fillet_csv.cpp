// The records export: one row per fillet, fields quoted as RFC 4180 asks, fragments listed.
#include <gtest/gtest.h>

#include <sstream>
#include <vector>

#include "service/fillet_csv.h"

using namespace rangex;

namespace {
// A minimal RFC 4180 reader (quoted fields, doubled quotes), independent of the writer.
std::vector<std::string> parse_row(const std::string& line) {
  std::vector<std::string> out(1);
  bool quoted = false;
  for (size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"')
        out.back() += '"', ++i;
      else if (c == '"')
        quoted = false;
      else
        out.back() += c;
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      out.emplace_back();
    } else if (c != '\r' && c != '\n') {
      out.back() += c;
    }
  }
  return out;
}
}  // namespace

TEST(FilletCsv, ReasonsWithCommasAndQuotesSurviveAndFragmentsAreCounted) {
  StoredFillet f;
  f.uid = 42, f.lane = 3, f.lane_fillet = 7, f.first_encoder = 123456, f.rows = 310;
  f.decision = "reject";
  f.reason = "bone at (12.5, 40.1), \"calcified\"";
  f.calibration_id = "cal,2026";
  f.decided_ns = 1'700'000'000'123'000'000;
  f.fragments.push_back({"bone", 12.5, 40.1, 3.2, -9.5, 1.0, 2.25, 1, 2, 3, 4});
  f.fragments.push_back({"air", 1, 2, 3, 4, 5, 0.5, 0, 0, 0, 0});
  const std::vector<std::string> head = parse_row(fillet_csv_header());
  const std::vector<std::string> row = parse_row(fillet_csv_row(f));
  ASSERT_EQ(row.size(), head.size());
  auto at = [&](const std::string& name) {
    for (size_t k = 0; k < head.size(); ++k)
      if (head[k] == name) return row[k];
    ADD_FAILURE() << "no column " << name;
    return std::string();
  };
  EXPECT_EQ(at("uid"), "42");
  EXPECT_EQ(at("lane"), "3");
  EXPECT_EQ(at("first_encoder"), "123456");
  EXPECT_EQ(at("reason"), f.reason);
  EXPECT_EQ(at("calibration"), "cal,2026");
  EXPECT_EQ(at("decided_utc"), "2023-11-14T22:13:20.123Z");
  EXPECT_EQ(at("bones"), "1");
  EXPECT_EQ(at("air_pockets"), "1");
  EXPECT_EQ(at("fragments"), "bone 12.5 40.1 3.2 -9.5 2.25; air 1 2 3 4 0.5");
  EXPECT_EQ(fillet_csv_row(f).substr(fillet_csv_row(f).size() - 2), "\r\n");
}
