// A failed learning's named fillets checked against the truth (offline/named_fillets.h):
// a clean one is kept, one holding bone or one no truth fillet explains stays out.
#include <gtest/gtest.h>

#include "offline/named_fillets.h"

using namespace rangex;

TEST(NamedFillets, ACleanOneIsKeptABonyOneAndAnUnexplainedOneStayOut) {
  // Two fillets on lane 0: 100-300 mm of belt without bone, 310-600 mm with two.
  const std::vector<TruthFillet> truth = {{0, 0, 100, 300, 0}, {0, 1, 310, 600, 2}};
  const std::vector<NamedFillet> named = {
      {0, 5, 95},    // its image starts 5 mm before the clean fillet
      {0, 6, 307},   // nearer the bony fillet than the clean one's end
      {0, 7, 1000},  // nothing of the truth there
      {1, 8, 150},   // another lane: no truth here
  };
  const NamedFilletCheck c = check_named_fillets(named, truth, 0);
  ASSERT_EQ(c.clean.size(), 1u);
  EXPECT_EQ(c.clean[0].id, 5);
  ASSERT_EQ(c.bony.size(), 3u);
  EXPECT_EQ(c.bony[0].id, 6);
  EXPECT_EQ(keep_list(c.clean), "0:5");
  EXPECT_NE(c.notes.find("fillet 5 (belt 95 mm): truth fillet 0, no bone: kept"),
            std::string::npos);
  EXPECT_NE(c.notes.find("truth fillet 1 holds 2 bone: left out"), std::string::npos);
  EXPECT_NE(c.notes.find("fillet 7 (belt 1000 mm): no truth fillet there"), std::string::npos);
  EXPECT_EQ(keep_list({{0, 3, 0}, {2, 11, 0}}), "0:3,2:11");
}

TEST(NamedFillets, NoneNamedNoneKept) {
  const NamedFilletCheck c = check_named_fillets({}, {{0, 0, 100, 300, 0}}, 0);
  EXPECT_TRUE(c.clean.empty() && c.bony.empty() && c.notes.empty());
  EXPECT_EQ(keep_list(c.clean), "");
}
