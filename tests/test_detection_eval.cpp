// The evaluation against the simulator's truth (offline/detection_eval.h): the truth's three
// layouts read, a bone matched within its tolerance, and a miss named with the bone it holds
// (its volume as a sphere's diameter: a flat 2 mm fragment holds the bone of a smaller sphere).
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "core/error.h"
#include "offline/detection_eval.h"

using namespace rangex;

TEST(DetectionEval, ReadsEachTruthLayoutAndRefusesOthers) {
  const std::string head = "fillet,kind,x_mm,b_mm,z_mm,xray_line,size_mm,calcification";
  auto one = [&](const std::string& extra_head, const std::string& row) {
    return parse_truth_fragments(head + extra_head + "\n" + row + "\n", 2);
  };
  const auto old8 = one("", "7,bone,1,100,5,300,2.5,0.8");
  ASSERT_EQ(old8.size(), 1u);
  EXPECT_EQ(old8[0].shape, "compact");
  EXPECT_EQ(old8[0].volume_mm3, -1);
  const auto old9 = one(",shape", "7,bone,1,100,5,300,2.5,0.8,needle");
  EXPECT_EQ(old9[0].shape, "needle");
  EXPECT_EQ(old9[0].volume_mm3, -1);
  const auto now = one(",shape,volume_mm3", "7,bone,1,100,5,300,2.5,0.8,chip,1.25");
  EXPECT_EQ(now[0].lane, 2);
  EXPECT_EQ(now[0].fillet, 7);
  EXPECT_DOUBLE_EQ(now[0].size_mm, 2.5);
  EXPECT_DOUBLE_EQ(now[0].xray_line, 300);
  EXPECT_DOUBLE_EQ(now[0].volume_mm3, 1.25);
  EXPECT_EQ(now[0].excess_mu, -1);
  const auto weighed =
      one(",shape,volume_mm3,excess_mu,meat_mu", "7,bone,1,100,5,300,2.5,0.8,chip,1.25,0.072,0.03");
  EXPECT_DOUBLE_EQ(weighed[0].volume_mm3, 1.25);
  EXPECT_DOUBLE_EQ(weighed[0].excess_mu, 0.072);
  EXPECT_DOUBLE_EQ(weighed[0].meat_mu, 0.03);
  EXPECT_THROW(one(",shape,volume_mm3,more", "7,bone,1,100,5,300,2.5,0.8,chip,1.25,9"), Error);
}

TEST(DetectionEval, AMissIsNamedWithTheBoneItHolds) {
  // Two calcified 2.0 mm fragments: one found 1 mm away, one missed. The missed one is flat:
  // semi-axes 1 x 0.5 x 0.4 mm, the volume of a 1.17 mm sphere.
  const double v = 4.0 / 3.0 * M_PI * 1.0 * 0.5 * 0.4;
  const std::string truth =
      "fillet,kind,x_mm,b_mm,z_mm,xray_line,size_mm,calcification,shape,volume_mm3\n"
      "1,bone,10,100,5,300,2.0,0.9,compact,4.19\n"
      "2,bone,-20,400,5,1000,2.0,0.76,compact," +
      std::to_string(v) +
      "\n"
      "3,bone,5,700,5,1800,2.5,0.8,compact,4.0\n";
  const std::string fillets =
      "fillet,x_center_mm,b_start_mm,b_end_mm,max_height_mm,bones\n"
      "1,0,50,150,20,1\n"
      "2,0,350,450,20,1\n"
      "3,0,650,750,20,1\n";
  RecordSet res;
  for (int k = 1; k <= 3; ++k) {
    FilletRecord f;
    f.fillet = k, f.y0_mm = 50 + 300 * (k - 1), f.y1_mm = f.y0_mm + 100;
    f.decision = k == 1 ? "reject" : k == 2 ? "pass" : "not_inspected";
    res.fillets.push_back(f);
  }
  FragmentRecord hit;
  hit.fillet = 1, hit.kind = "bone", hit.x_mm = 11, hit.y_mm = 100;
  res.fragments.push_back(hit);
  DetectionEval e;
  add_lane(e, parse_truth_fragments(truth, 0), parse_truth_fillets(fillets, 0), res);
  finish(e);
  EXPECT_DOUBLE_EQ(e.recall_calcified_2mm(), 1.0 / 3.0);
  // Every bone is judged, found or not, for the claims to be held against.
  ASSERT_EQ(e.judged.size(), 3u);
  EXPECT_TRUE(e.judged[0].found);
  EXPECT_FALSE(e.judged[1].found);
  EXPECT_NEAR(e.judged[1].volume_mm3, v, 1e-5);
  ASSERT_EQ(e.missed.size(), 2u);
  EXPECT_EQ(e.missed[0].fillet, 2);
  EXPECT_NEAR(e.missed[0].volume_mm3, v, 1e-5);
  // What became of each missed bone's fillet: passed down the line, or rejected unlooked.
  EXPECT_EQ(e.missed[0].fillet_decision, "pass");
  EXPECT_EQ(e.missed[1].fillet_decision, "not_inspected");
  // Of the three fillets holding calcified bone >= 2 mm, one went down the line.
  EXPECT_EQ(e.calcified_fillets, 3);
  EXPECT_EQ(e.calcified_passed, 1);
  const std::string line = missed_lines(e);
  EXPECT_NE(line.find("lane 0 fillet 2: 2.0 mm compact (the volume of a 1.2 mm sphere), "
                      "calcification 0.76\n"),
            std::string::npos)
      << line;
  EXPECT_NE(line.find("lane 0 fillet 3: 2.5 mm compact (the volume of a 2.0 mm sphere), "
                      "calcification 0.80; its fillet not inspected (rejected by the fail-safe)"),
            std::string::npos)
      << line;
}
