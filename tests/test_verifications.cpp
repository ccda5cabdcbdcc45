// A verification run counts the declared piece only on fillets that were inspected: a fillet
// the fail-safe rejects may name a bone found where it had thickness, but it does not show
// that the lane inspects.
#include <gtest/gtest.h>

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
