// Recording format: round trip, and bad recordings refused with the reason.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "core/plant_config.h"
#include "core/recording.h"
#include "offline/replay.h"
#include "temp_dir.h"

using namespace rangex;
namespace fs = std::filesystem;

namespace {
// A small hand-made recording: `lines` lines of frames filled with the line number.
void write_recording(const std::string& dir, int width, int height, int lines,
                     std::vector<int64_t> encoders = {}) {
  RecordingInfo info;
  info.lanes = {0};
  info.width = width;
  info.height = height;
  info.xray_pixels = 480;
  info.calibration_id = "dissertation-default";
  RecordingWriter w(dir, info);
  std::vector<uint8_t> f(size_t(width) * height);
  std::vector<uint16_t> x(480);
  for (int n = 0; n < lines; ++n) {
    std::fill(f.begin(), f.end(), uint8_t(n));
    std::fill(x.begin(), x.end(), uint16_t(1000 + n));
    w.append(0, {f.data(), f.data(), x.data(), encoders.empty() ? 100 + n : encoders[n]});
  }
  w.close();
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(Recording, RoundTrip) {
  test::TempDir t;
  write_recording(t.str("r"), 64, 16, 5);
  const RecordingReader r(t.str("r"));
  ASSERT_EQ(r.info().lines, 5);
  std::vector<uint8_t> c0(64 * 16 * 2), c1(64 * 16 * 2);
  std::vector<uint16_t> x(480 * 2);
  std::vector<int64_t> e(2);
  r.read(0, 3, 2, c0.data(), c1.data(), x.data(), e.data());
  EXPECT_EQ(c0[0], 3);
  EXPECT_EQ(c1[64 * 16], 4);
  EXPECT_EQ(x[480], 1004);
  EXPECT_EQ(e[1], 104);
}

TEST(Recording, DualEnergyCarriesTheHighLineAndSingleReadsAsBefore) {
  test::TempDir t;
  RecordingInfo info;
  info.lanes = {0};
  info.width = 8, info.height = 4, info.xray_pixels = 6;
  info.xray_energies = 2;
  {
    RecordingWriter w(t.str("d"), info);
    std::vector<uint8_t> f(32, 7);
    std::vector<uint16_t> lo(6), hi(6);
    for (int n = 0; n < 3; ++n) {
      std::fill(lo.begin(), lo.end(), uint16_t(100 + n));
      std::fill(hi.begin(), hi.end(), uint16_t(900 + n));
      w.append(0, {f.data(), f.data(), lo.data(), 10 + n, hi.data()});
    }
    // A line without its high line is refused, not written half.
    EXPECT_NE(error_of([&] {
                w.append(0, {f.data(), f.data(), lo.data(), 13});
              }).find("without its high X-ray line"),
              std::string::npos);
  }
  const RecordingReader r(t.str("d"));
  EXPECT_EQ(r.info().xray_energies, 2);
  std::vector<uint16_t> lo(12), hi(12);
  std::vector<int64_t> e(2);
  r.read(0, 1, 2, nullptr, nullptr, lo.data(), e.data());
  r.read_high(0, 1, 2, hi.data());
  EXPECT_EQ(lo[6], 102);
  EXPECT_EQ(hi[0], 901);
  EXPECT_EQ(hi[11], 902);
  // Truncated high lines are refused like any array.
  fs::resize_file(t.path() / "d" / "lane0" / "xray_high.u16", 12 * 2);
  EXPECT_NE(error_of([&] { RecordingReader bad(t.str("d")); }).find("xray_high.u16 is truncated"),
            std::string::npos);
  // A recording of one energy has no xray_energies key and no high line.
  write_recording(t.str("s"), 8, 4, 2);
  std::ifstream y(t.path() / "s" / "recording.yaml");
  const std::string yaml((std::istreambuf_iterator<char>(y)), std::istreambuf_iterator<char>());
  EXPECT_EQ(yaml.find("xray_energies"), std::string::npos);
  const RecordingReader s(t.str("s"));
  EXPECT_EQ(s.info().xray_energies, 1);
  EXPECT_NE(error_of([&] { s.read_high(0, 0, 1, hi.data()); }).find("one X-ray energy"),
            std::string::npos);
}

TEST(Recording, TruncatedFileIsRefusedWithSizes) {
  test::TempDir t;
  write_recording(t.str("r"), 64, 16, 5);
  fs::resize_file(t.path() / "r" / "lane0" / "cam1.u8", 64 * 16 * 3 + 100);
  const std::string e = error_of([&] { RecordingReader r(t.str("r")); });
  EXPECT_NE(e.find("lane 0: cam1.u8 is truncated"), std::string::npos) << e;
  EXPECT_NE(e.find("holds 3 whole lines"), std::string::npos) << e;
}

TEST(Recording, NotARecordingAndExistingFolder) {
  test::TempDir t;
  EXPECT_NE(error_of([&] { RecordingReader r(t.str()); }).find("no recording.yaml"),
            std::string::npos);
  write_recording(t.str("r"), 64, 16, 1);
  EXPECT_NE(
      error_of([&] { write_recording(t.str("r"), 64, 16, 1); }).find("already holds a recording"),
      std::string::npos);
}

TEST(Recording, WrongFrameSizeAgainstConfig) {
  test::TempDir t;
  write_recording(t.str("r"), 320, 200, 3);
  const PlantConfig plant = default_plant_config(1);
  const std::string e = error_of([&] { replay_recording(RecordingReader(t.str("r")), plant, {}); });
  EXPECT_NE(e.find("recording frames are 320x200 but the plant configuration says 640x200"),
            std::string::npos)
      << e;
}

TEST(Recording, EnergiesAgainstConfigAreChecked) {
  test::TempDir t;
  write_recording(t.str("r"), 640, 200, 2);
  PlantConfig plant = default_plant_config(1);
  plant.lanes[0].xray.energies = 2;
  const std::string e = error_of([&] { replay_recording(RecordingReader(t.str("r")), plant, {}); });
  EXPECT_NE(e.find("recording has 1 X-ray energies but the plant configuration says 2"),
            std::string::npos)
      << e;
}

TEST(Recording, CalibrationMismatchIsRefused) {
  test::TempDir t;
  write_recording(t.str("r"), 640, 200, 2);
  PlantConfig plant = default_plant_config(1);
  plant.calibration_id = "line-3-2026-11-01";
  const std::string e = error_of([&] { replay_recording(RecordingReader(t.str("r")), plant, {}); });
  EXPECT_NE(e.find("calibration mismatch"), std::string::npos) << e;
}

TEST(Recording, EncoderGoingBackwardsOrRepeatingIsRefused) {
  test::TempDir t;
  write_recording(t.str("back"), 640, 200, 3, {10, 11, 9});
  write_recording(t.str("dup"), 640, 200, 3, {10, 11, 11});
  const PlantConfig plant = default_plant_config(1);
  EXPECT_NE(error_of([&] {
              replay_recording(RecordingReader(t.str("back")), plant, {});
            }).find("goes backwards"),
            std::string::npos);
  EXPECT_NE(
      error_of([&] { replay_recording(RecordingReader(t.str("dup")), plant, {}); }).find("repeats"),
      std::string::npos);
}
