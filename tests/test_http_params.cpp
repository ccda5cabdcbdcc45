// The HTTP API's parameters: a wrong one is a BadRequest naming it and what it must be.
#include <gtest/gtest.h>

#include "service/http_params.h"
#include "service/request_end.h"

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
  // Digits after one optional sign, whole: std::stoll took a leading space.
  for (const char* bad : {" 2", "2 ", "", "+", "-", "+-5", "0x10", "2abc"})
    EXPECT_EQ(refusal([&] {
                fillet_query({{"lane", bad}});
              }),
              "lane must be an integer (got '" + std::string(bad) + "')")
        << "'" << bad << "'";
  EXPECT_EQ(fillet_query({{"lane", "+4"}}).lane, 4);
  EXPECT_EQ(parse_int("x", "-3", -5, 5), -3);
  EXPECT_EQ(refusal([] { parse_int("x", "-99999999999999999999", INT64_MIN, 0); }),
            "x must be within -9223372036854775808..0 (got -99999999999999999999)");
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

TEST(HttpParams, AVerificationBodyIsCheckedFieldByField) {
  const VerificationRequest r = verification_body(
      R"({"piece": "2 mm sphere", "x_mm": -12.5, "tolerance_mm": 4, "fillets": 7})");
  EXPECT_EQ(r.piece, "2 mm sphere");
  EXPECT_EQ(r.x_mm, -12.5);
  EXPECT_EQ(r.tolerance_mm, 4);
  EXPECT_EQ(r.fillets, 7);
  EXPECT_EQ(verification_body(R"({"piece": "p", "x_mm": 1})").fillets, 0);  // plant.yaml's
  EXPECT_NE(refusal([] { verification_body("[1]"); }).find("a JSON object"), std::string::npos);
  EXPECT_NE(refusal([] { verification_body(R"({"x_mm": 1})"); }).find("piece must be"),
            std::string::npos);
  EXPECT_NE(refusal([] {
              verification_body(R"({"piece": "p", "x_mm": "3"})");
            }).find("x_mm must be a number"),
            std::string::npos);
  EXPECT_NE(refusal([] {
              verification_body(R"({"piece": "p", "x_mm": 1, "fillets": 2.5})");
            }).find("fillets must be an integer"),
            std::string::npos);
  EXPECT_NE(refusal([] {
              verification_body(R"({"piece": "p", "x_mm": 1, "lane": 2})");
            }).find("unknown field 'lane'"),
            std::string::npos);
}

TEST(HttpParams, ARequestEndsAfterItsHeadAndItsSmallBody) {
  const std::string head = "POST /a HTTP/1.1\r\nHost: h\r\nContent-Length: 5\r\n\r\n";
  EXPECT_FALSE(request_end(head.substr(0, 20), 1024, 64).complete);  // the head still coming
  EXPECT_FALSE(request_end(head + "12", 1024, 64).complete);         // the body still coming
  const RequestEnd e = request_end(head + "12345GET /next", 1024, 64);
  EXPECT_TRUE(e.complete);
  EXPECT_EQ(e.bytes, head.size() + 5);  // the next request stays behind
  // A body over the bound ends the request at its head (the worker refuses it unread).
  const std::string big = "POST /a HTTP/1.1\r\ncontent-length:  100000 \r\n\r\n";
  EXPECT_EQ(request_end(big, 1024, 64).bytes, big.size());
  EXPECT_EQ(announced_body(big), 100000u);
  EXPECT_EQ(announced_body("POST / HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n"), SIZE_MAX);
  EXPECT_EQ(announced_body("POST / HTTP/1.1\r\nContent-Length: 5x\r\n\r\n"), SIZE_MAX);
  EXPECT_EQ(announced_body("GET / HTTP/1.1\r\n\r\n"), 0u);
  EXPECT_TRUE(request_end(std::string(2000, 'a'), 1024, 64).too_large);  // no head in 1 kB
}
