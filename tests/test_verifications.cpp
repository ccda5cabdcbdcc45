// A verification run counts the declared piece only on fillets that were inspected: a fillet
// the fail-safe rejects may name a bone found where it had thickness, but it does not show
// that the lane inspects.
#include <gtest/gtest.h>

#include "core/error.h"
#include "core/plant_config.h"
#include "service/verifications.h"
#include "store/store.h"
#include "temp_dir.h"

using namespace rangex;

namespace {
StoredFillet fillet(const char* decision, double bone_x_mm) {
  StoredFillet f;
  f.lane = 0;
  f.rows = 200;
  f.decision = decision;
  f.fragments.push_back({"bone", bone_x_mm, 150.0, 3.0, -9.0, 0.5});
  return f;
}
}  // namespace

TEST(Verifications, APieceOnAFilletNotInspectedDoesNotVerifyTheLane) {
  test::TempDir t;
  const PlantConfig plant = load_plant_config(RANGEX_SOURCE_DIR "/config/plant.yaml");
  Store store(t.str());
  Verifications v(plant, store);
  v.start({0, "2 mm calcified sphere", 20, 5, 2}, "alice");
  v.decided(fillet("not_inspected", 21));  // the piece, found where the fillet had thickness
  EXPECT_TRUE(v.lane(0).running);
  v.decided(fillet("not_inspected", 20));
  LaneVerification r = v.lane(0);
  ASSERT_TRUE(r.last);
  EXPECT_FALSE(r.last->passed) << r.last->detail;

  v.start({0, "2 mm calcified sphere", 20, 5, 2}, "alice");
  v.decided(fillet("reject", 60));  // a bone elsewhere
  v.decided(fillet("reject", 22));
  r = v.lane(0);
  ASSERT_TRUE(r.last);
  EXPECT_TRUE(r.last->passed) << r.last->detail;
  EXPECT_NEAR(r.last->found_x_mm, 22, 1e-9);
}

// The piece's name is audited and shown, one line: an empty one, one of more than 200 bytes,
// one with a quote or a control character is refused, naming what is wrong.
TEST(Verifications, APieceNameIsOneLineWithoutQuotes) {
  test::TempDir t;
  const PlantConfig plant = load_plant_config(RANGEX_SOURCE_DIR "/config/plant.yaml");
  Store store(t.str());
  Verifications v(plant, store);
  auto refusal = [&](const std::string& piece) {
    try {
      v.start({0, piece, 20, 5, 2}, "alice");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(refusal(""), "the test piece's name is empty");
  EXPECT_EQ(refusal(std::string(201, 'p')),
            "the test piece's name is 201 bytes, more than the 200 allowed");
  EXPECT_EQ(refusal("2 mm\nsphere"),
            "the test piece's name '2 mm...' holds the control character 0x0A at 4");
  EXPECT_EQ(refusal("2 mm 'sphere'"),
            "the test piece's name holds a quote (name it e.g. 2 mm calcified sphere)");
  EXPECT_FALSE(v.lane(0).running);
  EXPECT_EQ(refusal(std::string(200, 'p')), "");
  EXPECT_TRUE(v.lane(0).running);
}
