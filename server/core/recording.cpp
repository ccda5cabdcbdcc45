#include "core/recording.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.h"

namespace fs = std::filesystem;

namespace rangex {

namespace {
constexpr const char* kFormat = "rangex-recording/1";

FILE* open_or_fail(const fs::path& p, const char* mode) {
  FILE* f = std::fopen(p.c_str(), mode);
  if (!f) fail(p.string(), ": cannot open (", std::strerror(errno), ")");
  return f;
}

void write_all(FILE* f, const void* data, size_t bytes, const std::string& what) {
  if (bytes && std::fwrite(data, 1, bytes, f) != bytes) fail(what, ": write failed");
}
}  // namespace

struct RecordingWriter::LaneFiles {
  int id;
  fs::path dir;
  FILE* cam0 = nullptr;
  FILE* cam1 = nullptr;
  FILE* xray = nullptr;
  FILE* xray_high = nullptr;
  FILE* encoder = nullptr;
  std::vector<std::pair<std::string, FILE*>> truth;
  int64_t lines = 0;
  ~LaneFiles() {
    for (FILE* f : {cam0, cam1, xray, xray_high, encoder})
      if (f) std::fclose(f);
    for (auto& [n, f] : truth) std::fclose(f);
  }
};

RecordingWriter::RecordingWriter(const std::string& dir, RecordingInfo info)
    : dir_(dir), info_(std::move(info)) {
  if (info_.xray_energies != 1 && info_.xray_energies != 2)
    fail("recording ", dir, ": xray_energies must be 1 or 2 (got ", info_.xray_energies, ")");
  if (fs::exists(fs::path(dir) / "recording.yaml"))
    fail(dir, ": already holds a recording; choose an empty folder");
  fs::create_directories(dir);
  for (int id : info_.lanes) {
    auto lf = std::make_unique<LaneFiles>();
    lf->id = id;
    lf->dir = fs::path(dir) / ("lane" + std::to_string(id));
    fs::create_directories(lf->dir);
    lf->cam0 = open_or_fail(lf->dir / "cam0.u8", "wb");
    lf->cam1 = open_or_fail(lf->dir / "cam1.u8", "wb");
    lf->xray = open_or_fail(lf->dir / "xray.u16", "wb");
    if (info_.xray_energies == 2) lf->xray_high = open_or_fail(lf->dir / "xray_high.u16", "wb");
    lf->encoder = open_or_fail(lf->dir / "encoder.i64", "wb");
    lanes_.push_back(std::move(lf));
  }
}

RecordingWriter::~RecordingWriter() {
  try {
    close();
  } catch (...) {
  }
}

RecordingWriter::LaneFiles& RecordingWriter::files(int lane) {
  for (auto& l : lanes_)
    if (l->id == lane) return *l;
  fail("recording ", dir_, ": unknown lane ", lane);
}

void RecordingWriter::append(int lane, const LineView& line) {
  LaneFiles& f = files(lane);
  // Checked before any byte is written: a line is in every file or in none.
  if (f.xray_high && !line.xray_high)
    fail("recording ", dir_, ": lane ", lane, ": a line without its high X-ray line");
  const size_t frame = size_t(info_.width) * info_.height;
  write_all(f.cam0, line.cam0, frame, "cam0.u8");
  write_all(f.cam1, line.cam1, frame, "cam1.u8");
  write_all(f.xray, line.xray, size_t(info_.xray_pixels) * 2, "xray.u16");
  if (f.xray_high)
    write_all(f.xray_high, line.xray_high, size_t(info_.xray_pixels) * 2, "xray_high.u16");
  write_all(f.encoder, &line.encoder, 8, "encoder.i64");
  ++f.lines;
}

void RecordingWriter::append_truth(int lane, const std::string& name, const void* data,
                                   size_t bytes) {
  LaneFiles& f = files(lane);
  auto it = std::find_if(f.truth.begin(), f.truth.end(), [&](auto& p) { return p.first == name; });
  if (it == f.truth.end()) {
    fs::create_directories(f.dir / "truth");
    f.truth.emplace_back(name, open_or_fail(f.dir / "truth" / name, "wb"));
    it = f.truth.end() - 1;
  }
  write_all(it->second, data, bytes, name);
}

void RecordingWriter::write_truth_text(int lane, const std::string& name, const std::string& text) {
  LaneFiles& f = files(lane);
  fs::create_directories(f.dir / "truth");
  std::ofstream out(f.dir / "truth" / name);
  out << text;
  if (!out) fail((f.dir / "truth" / name).string(), ": write failed");
}

void RecordingWriter::close() {
  if (closed_) return;
  closed_ = true;
  int64_t lines = -1;
  for (auto& l : lanes_) {
    if (lines >= 0 && l->lines != lines)
      fail("recording ", dir_, ": lane ", l->id, " has ", l->lines, " lines, others ", lines);
    lines = l->lines;
  }
  info_.lines = std::max<int64_t>(lines, 0);
  lanes_.clear();  // flushes and closes every file
  YAML::Emitter y;
  y << YAML::BeginMap << YAML::Key << "format" << YAML::Value << kFormat;
  y << YAML::Key << "lanes" << YAML::Value << YAML::Flow << info_.lanes;
  y << YAML::Key << "frame" << YAML::Value << YAML::Flow << YAML::BeginMap << YAML::Key << "width"
    << YAML::Value << info_.width << YAML::Key << "height" << YAML::Value << info_.height
    << YAML::EndMap;
  y << YAML::Key << "xray_pixels" << YAML::Value << info_.xray_pixels;
  // Written for dual energy only: a recording of one energy reads as it always did.
  if (info_.xray_energies == 2) y << YAML::Key << "xray_energies" << YAML::Value << 2;
  y << YAML::Key << "lines" << YAML::Value << info_.lines;
  y << YAML::Key << "encoder_step_mm" << YAML::Value << info_.encoder_step_mm;
  y << YAML::Key << "calibration_id" << YAML::Value << info_.calibration_id;
  y << YAML::Key << "truth" << YAML::Value << info_.has_truth;
  y << YAML::Key << "seed" << YAML::Value << info_.seed;
  y << YAML::EndMap;
  std::ofstream out(fs::path(dir_) / "recording.yaml");
  out << y.c_str() << "\n";
  if (!out) fail(dir_, "/recording.yaml: write failed");
}

RecordingReader::RecordingReader(const std::string& dir) : dir_(dir) {
  const fs::path meta = fs::path(dir) / "recording.yaml";
  if (!fs::exists(meta)) fail(dir, ": not a recording (no recording.yaml)");
  YAML::Node y;
  try {
    y = YAML::LoadFile(meta.string());
    if (!y["format"] || y["format"].as<std::string>() != kFormat)
      fail(meta.string(), ": format is not ", kFormat);
    info_.lanes = y["lanes"].as<std::vector<int>>();
    info_.width = y["frame"]["width"].as<int>();
    info_.height = y["frame"]["height"].as<int>();
    info_.xray_pixels = y["xray_pixels"].as<int>();
    info_.lines = y["lines"].as<int64_t>();
    info_.encoder_step_mm = y["encoder_step_mm"].as<double>();
    info_.calibration_id = y["calibration_id"].as<std::string>();
    info_.has_truth = y["truth"] && y["truth"].as<bool>();
    if (y["seed"]) info_.seed = y["seed"].as<uint64_t>();
    if (y["xray_energies"]) info_.xray_energies = y["xray_energies"].as<int>();
  } catch (const YAML::Exception& e) {
    fail(meta.string(), ": malformed (", e.what(), ")");
  }
  if (info_.width <= 0 || info_.height <= 0 || info_.xray_pixels <= 0 || info_.lines < 0 ||
      info_.lanes.empty())
    fail(meta.string(), ": sizes must be positive and at least one lane listed");
  if (info_.xray_energies != 1 && info_.xray_energies != 2)
    fail(meta.string(), ": xray_energies must be 1 or 2 (got ", info_.xray_energies, ")");
  const size_t frame = size_t(info_.width) * info_.height;
  struct Expect {
    const char* name;
    size_t per_line;
  };
  std::vector<Expect> files = {Expect{"cam0.u8", frame}, Expect{"cam1.u8", frame},
                               Expect{"xray.u16", size_t(info_.xray_pixels) * 2},
                               Expect{"encoder.i64", 8}};
  if (info_.xray_energies == 2) files.push_back({"xray_high.u16", size_t(info_.xray_pixels) * 2});
  for (int lane : info_.lanes) {
    for (const Expect& e : files) {
      const fs::path p = fs::path(lane_dir(lane)) / e.name;
      if (!fs::exists(p)) fail("lane ", lane, ": ", e.name, " is missing in ", dir);
      const auto size = fs::file_size(p);
      const auto want = e.per_line * size_t(info_.lines);
      if (size != want)
        fail("lane ", lane, ": ", e.name, " is ", size < want ? "truncated" : "too long", ": ",
             size, " bytes for ", info_.lines, " lines of ", e.per_line, " bytes (expected ", want,
             ", holds ", size / e.per_line, " whole lines)");
    }
  }
}

std::string RecordingReader::lane_dir(int lane) const {
  return (fs::path(dir_) / ("lane" + std::to_string(lane))).string();
}

RecordingReader::MappedFrames RecordingReader::map_frames(int lane) const {
  if (std::find(info_.lanes.begin(), info_.lanes.end(), lane) == info_.lanes.end())
    fail("recording ", dir_, ": unknown lane ", lane);
  MappedFrames m;
  m.frame_bytes = size_t(info_.width) * info_.height;
  const char* names[2] = {"cam0.u8", "cam1.u8"};
  for (int c = 0; c < 2; ++c) {
    const std::string path = (fs::path(lane_dir(lane)) / names[c]).string();
    m.cam[c] = std::make_unique<MappedFile>(path);
    if (m.cam[c]->size() < m.frame_bytes * size_t(info_.lines))
      fail("lane ", lane, ": ", names[c], " holds ", m.cam[c]->size(), " bytes, fewer than ",
           info_.lines, " frames of ", m.frame_bytes);
    m.cam[c]->advise_sequential();
  }
  return m;
}

void RecordingReader::read_high(int lane, int64_t first, int64_t count, uint16_t* xray_high) const {
  if (info_.xray_energies != 2) fail("recording ", dir_, ": one X-ray energy; it has no high line");
  read(lane, first, count, nullptr, nullptr, nullptr, nullptr, xray_high);
}

void RecordingReader::read(int lane, int64_t first, int64_t count, uint8_t* cam0, uint8_t* cam1,
                           uint16_t* xray, int64_t* encoder) const {
  read(lane, first, count, cam0, cam1, xray, encoder, nullptr);
}

void RecordingReader::read(int lane, int64_t first, int64_t count, uint8_t* cam0, uint8_t* cam1,
                           uint16_t* xray, int64_t* encoder, uint16_t* xray_high) const {
  if (std::find(info_.lanes.begin(), info_.lanes.end(), lane) == info_.lanes.end())
    fail("recording ", dir_, ": unknown lane ", lane);
  if (first < 0 || count < 0 || first + count > info_.lines)
    fail("recording ", dir_, ": lines ", first, "..", first + count, " out of range (", info_.lines,
         " lines)");
  const size_t frame = size_t(info_.width) * info_.height;
  auto chunk = [&](const char* name, size_t per_line, void* dst) {
    if (!dst) return;
    FILE* f = open_or_fail(fs::path(lane_dir(lane)) / name, "rb");
    std::fseek(f, long(per_line * first), SEEK_SET);
    const size_t n = std::fread(dst, 1, per_line * count, f);
    std::fclose(f);
    if (n != per_line * size_t(count)) fail("lane ", lane, ": ", name, ": short read");
  };
  chunk("cam0.u8", frame, cam0);
  chunk("cam1.u8", frame, cam1);
  chunk("xray.u16", size_t(info_.xray_pixels) * 2, xray);
  chunk("encoder.i64", 8, encoder);
  chunk("xray_high.u16", size_t(info_.xray_pixels) * 2, xray_high);
}

std::vector<float> RecordingReader::truth_f32(int lane, const std::string& name,
                                              size_t per_line) const {
  const fs::path p = fs::path(lane_dir(lane)) / "truth" / name;
  if (!fs::exists(p)) return {};
  const size_t want = per_line * size_t(info_.lines) * sizeof(float);
  if (fs::file_size(p) != want)
    fail("lane ", lane, ": truth/", name, " holds ", fs::file_size(p), " bytes, expected ", want);
  std::vector<float> v(per_line * size_t(info_.lines));
  FILE* f = open_or_fail(p, "rb");
  const size_t n = std::fread(v.data(), 1, want, f);
  std::fclose(f);
  if (n != want) fail("lane ", lane, ": truth/", name, ": short read");
  return v;
}

std::string RecordingReader::truth_text(int lane, const std::string& name) const {
  std::ifstream in(fs::path(lane_dir(lane)) / "truth" / name);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace rangex
