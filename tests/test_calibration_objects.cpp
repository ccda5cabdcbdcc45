// The calibration objects' drawings (YAML): written and read back unchanged; bad values
// refused naming the key.
#include <gtest/gtest.h>

#include <functional>

#include "core/calibration_objects.h"
#include "core/error.h"

namespace rangex {
namespace {

std::string refusal(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(CalibrationObjects, DrawingsRoundTrip) {
  const Staircase s;
  const Staircase s2 = parse_staircase(to_yaml(s), "s.yaml");
  EXPECT_EQ(s2.heights_mm, s.heights_mm);
  EXPECT_DOUBLE_EQ(s2.x0_mm, s.x0_mm);
  const PinPhantom p = PinPhantom::figure27();
  const PinPhantom p2 = parse_pin_phantom(to_yaml(p), "p.yaml");
  ASSERT_EQ(p2.rows.size(), p.rows.size());
  EXPECT_EQ(p2.rows[3].x_mm, p.rows[3].x_mm);
  EXPECT_DOUBLE_EQ(p2.rows[3].z_mm, p.rows[3].z_mm);
  const BlockSet b = BlockSet::standard();
  const BlockSet b2 = parse_block_set(to_yaml(b), "b.yaml");
  ASSERT_EQ(b2.blocks.size(), b.blocks.size());
  EXPECT_DOUBLE_EQ(b2.blocks[2].height_mm, b.blocks[2].height_mm);
}

TEST(CalibrationObjects, BadValuesAreRefusedByKey) {
  EXPECT_NE(refusal([] {
              parse_staircase("staircase: {heights_mm: [5, .nan]}", "s.yaml");
            }).find("staircase.heights_mm[1]: not a finite number"),
            std::string::npos);
  EXPECT_NE(refusal([] {
              parse_staircase("staircase: {heights_mm: []}", "s.yaml");
            }).find("expected a list"),
            std::string::npos);
  EXPECT_NE(refusal([] {
              parse_pin_phantom("pin_phantom: {radius_mm: -1, rows: [{z_mm: 10, x_mm: [0]}]}",
                                "p.yaml");
            }).find("radius_mm: must be > 0"),
            std::string::npos);
  EXPECT_NE(refusal([] {
              parse_pin_phantom("pin_phantom: {rows: [{x_mm: [0]}]}", "p.yaml");
            }).find("rows[0].z_mm"),
            std::string::npos);
  EXPECT_NE(refusal([] {
              parse_block_set("blocks: {list: [{width_mm: 10, length_mm: 0, height_mm: 5}]}",
                              "b.yaml");
            }).find("blocks.list[0].length_mm: must be > 0"),
            std::string::npos);
  EXPECT_NE(refusal([] { parse_block_set("blocks: [1, 2", "b.yaml"); }).find("b.yaml"),
            std::string::npos);
}

}  // namespace
}  // namespace rangex
