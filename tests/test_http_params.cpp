// The HTTP API's parameters: a wrong one is a BadRequest naming it and what it must be.
#include <gtest/gtest.h>

#include "service/http_params.h"

using namespace rangex;

namespace {
std::string refusal(const std::function<void()>& f) {
  try {
    f();
  } catch (const BadRequest& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(HttpParams, AFilletQueryIsReadAndBadValuesAreNamed) {
  const FilletQuery q = fillet_query(
      {{"lane", "2"}, {"decision", "reject"}, {"from_ns", "5"}, {"limit", "7"}, {"newest", "1"}});
  EXPECT_EQ(q.lane, 2);
  EXPECT_EQ(q.decision, "reject");
  EXPECT_EQ(q.from_ns, 5);
  EXPECT_EQ(q.limit, 7);
  EXPECT_TRUE(q.newest_first);
  EXPECT_EQ(fillet_query({}).limit, 200);
  EXPECT_EQ(refusal([] {
              fillet_query({{"limit", "0"}});
            }),
            "limit must be within 1..10000 (got 0)");
  EXPECT_EQ(refusal([] {
              fillet_query({{"lane", "two"}});
            }),
            "lane must be an integer (got 'two')");
  EXPECT_EQ(refusal([] {
              fillet_query({{"from_ns", "1e9"}});
            }),
            "from_ns must be an integer (got '1e9')");
  EXPECT_EQ(refusal([] {
              fillet_query({{"decision", "maybe"}});
            }),
            "decision must be pass, reject or not_inspected (got 'maybe')");
}

TEST(HttpParams, ListsAndPathPartsAreChecked) {
  EXPECT_EQ(int_set({{"lanes", "1,,3,1"}}, "lanes"), (std::set<int>{1, 3}));
  EXPECT_EQ(decision_set({{"decisions", "reject,pass"}}, "decisions"),
            (std::set<std::string>{"pass", "reject"}));
  EXPECT_NE(refusal([] {
              int_set({{"lanes", "1,x"}}, "lanes");
            }).find("lanes must be an integer"),
            std::string::npos);
  EXPECT_EQ(parse_uid("42"), 42);
  // Found while writing the fuzz target: a 20-digit uid threw out_of_range (answered 500).
  EXPECT_EQ(refusal([] { parse_uid("99999999999999999999"); }),
            "the fillet uid must be within 1..9223372036854775807 (got 99999999999999999999)");
  EXPECT_NE(refusal([] { parse_uid("0"); }).find("within 1.."), std::string::npos);
  EXPECT_EQ(checked_image_kind("residual"), "residual");
  EXPECT_NE(refusal([] { checked_image_kind("raw"); }).find("image kind must be"),
            std::string::npos);
}
