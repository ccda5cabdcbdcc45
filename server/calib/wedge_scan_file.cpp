#include "calib/wedge_scan_file.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.h"
#include "core/text_file.h"

namespace fs = std::filesystem;

namespace rangex {

namespace {

std::vector<uint16_t> read_lines(const fs::path& p, size_t count) {
  // The drawing's size is checked against the file before anything is allocated for it.
  std::error_code ec;
  const auto bytes = fs::file_size(p, ec);
  if (ec) fail(p.string(), ": cannot open");
  if (bytes < count * 2)
    fail(p.string(), ": shorter than the ", count, " readings wedge.yaml asks for");
  std::vector<uint16_t> v(count);
  std::ifstream in(p, std::ios::binary);
  if (!in) fail(p.string(), ": cannot open");
  if (!in.read(reinterpret_cast<char*>(v.data()), std::streamsize(count * 2)))
    fail(p.string(), ": shorter than the ", count, " readings wedge.yaml asks for");
  return v;
}

std::string list(const std::vector<double>& v) {
  std::ostringstream o;
  o << "[";
  for (size_t i = 0; i < v.size(); ++i) o << (i ? ", " : "") << v[i];
  o << "]";
  return o.str();
}

}  // namespace

std::string wedge_layout_yaml(const WedgeLayout& w, int pixels) {
  std::ostringstream o;
  o << "# A-150 steps across the detector, aluminium steps along the belt (docs/dual-energy.md)\n"
    << "pixels: " << pixels << "\nlines: " << w.lines()
    << "\nwedge:\n  a150_mm: " << list(w.a150_mm) << "\n  al_mm: " << list(w.al_mm)
    << "\n  first_pixel: " << w.first_pixel << "\n  step_pixels: " << w.step_pixels
    << "\n  margin_pixels: " << w.margin_pixels << "\n  open_lines: " << w.open_lines
    << "\n  step_lines: " << w.step_lines << "\n  margin_lines: " << w.margin_lines << "\n";
  return o.str();
}

void write_wedge_scan(const std::string& dir, const WedgeLayout& w, int pixels,
                      const std::vector<uint16_t>& low, const std::vector<uint16_t>& high) {
  fs::create_directories(dir);
  {
    std::ofstream y(fs::path(dir) / "wedge.yaml");
    y << wedge_layout_yaml(w, pixels);
    if (!y) fail((fs::path(dir) / "wedge.yaml").string(), ": write failed");
  }
  for (auto [name, v] : {std::pair{"low.u16", &low}, std::pair{"high.u16", &high}}) {
    std::ofstream out(fs::path(dir) / name, std::ios::binary);
    out.write(reinterpret_cast<const char*>(v->data()), std::streamsize(v->size() * 2));
    if (!out) fail((fs::path(dir) / name).string(), ": write failed");
  }
}

WedgeScan read_wedge_scan(const std::string& dir, const FanBeam& beam) {
  const fs::path yaml = fs::path(dir) / "wedge.yaml";
  if (!fs::exists(yaml)) fail(dir, ": no wedge.yaml (not a dual-energy wedge scan)");
  WedgeLayout w;
  int pixels = 0, lines = 0;
  try {
    const YAML::Node n = YAML::Load(read_text_file(yaml.string()));
    pixels = n["pixels"].as<int>();
    lines = n["lines"].as<int>();
    const YAML::Node d = n["wedge"];
    w.a150_mm = d["a150_mm"].as<std::vector<double>>();
    w.al_mm = d["al_mm"].as<std::vector<double>>();
    w.first_pixel = d["first_pixel"].as<int>();
    w.step_pixels = d["step_pixels"].as<int>();
    w.margin_pixels = d["margin_pixels"].as<int>();
    w.open_lines = d["open_lines"].as<int>();
    w.step_lines = d["step_lines"].as<int>();
    w.margin_lines = d["margin_lines"].as<int>();
  } catch (const YAML::Exception& e) {
    fail(yaml.string(), ": ", e.what());
  }
  if (pixels != beam.pixels)
    fail(yaml.string(), ": ", pixels, " pixels, but the lane's detector has ", beam.pixels);
  if (w.a150_mm.empty() || w.al_mm.empty()) fail(yaml.string(), ": no steps");
  if (w.first_pixel < 0 || w.last_pixel() > pixels)
    fail(yaml.string(), ": the steps lie outside the detector's ", pixels, " pixels");
  if (w.step_pixels - 2 * w.margin_pixels < 2 || w.step_lines - 2 * w.margin_lines < 2 ||
      w.margin_pixels < 0 || w.margin_lines < 0)
    fail(yaml.string(), ": a step's middle holds fewer than 2 pixels or lines");
  if (w.open_lines < 10) fail(yaml.string(), ": needs at least 10 lines of bare belt first");
  if (lines != w.lines())
    fail(yaml.string(), ": ", lines, " lines, but its steps take ", w.lines());
  const size_t n = size_t(lines) * pixels;
  const auto low = read_lines(fs::path(dir) / "low.u16", n);
  const auto high = read_lines(fs::path(dir) / "high.u16", n);

  WedgeScan scan;
  // The open beam: the bare belt's lines, over the pixels the steps use.
  double s_lo = 0, s_hi = 0;
  long count = 0;
  for (int l = 0; l < w.open_lines; ++l)
    for (int p = w.first_pixel; p < w.last_pixel(); ++p) {
      s_lo += low[size_t(l) * pixels + p], s_hi += high[size_t(l) * pixels + p];
      ++count;
    }
  scan.open_low = s_lo / double(count), scan.open_high = s_hi / double(count);

  for (size_t j = 0; j < w.al_mm.size(); ++j)
    for (size_t i = 0; i < w.a150_mm.size(); ++i) {
      const int p0 = w.first_pixel + int(i) * w.step_pixels + w.margin_pixels,
                p1 = w.first_pixel + int(i + 1) * w.step_pixels - w.margin_pixels;
      const int l0 = w.open_lines + int(j) * w.step_lines + w.margin_lines,
                l1 = w.open_lines + int(j + 1) * w.step_lines - w.margin_lines;
      const int cols = p1 - p0, rows = l1 - l0;
      WedgeStep st;
      double factor = 0;
      std::vector<double> col_lo(size_t(cols), 0.0);
      double q_lo = 0, q_hi = 0;
      for (int p = p0; p < p1; ++p) {
        factor += beam.slab_path_factor(p) / cols;
        for (int l = l0; l < l1; ++l) {
          const double lo = low[size_t(l) * pixels + p], hi = high[size_t(l) * pixels + p];
          col_lo[size_t(p - p0)] += lo / rows;
          st.low += lo, st.high += hi, q_lo += lo * lo, q_hi += hi * hi;
        }
      }
      const double m = double(cols) * rows;
      st.low /= m, st.high /= m;
      st.var_low = (q_lo - m * st.low * st.low) / (m - 1);
      st.var_high = (q_hi - m * st.high * st.high) / (m - 1);
      st.samples = cols * rows;
      st.a150_mm = w.a150_mm[i] * factor, st.al_mm = w.al_mm[j] * factor;
      // Flat: the columns' means about a line across the step (the slant tilts a step a
      // little) within their noise; an edge inside the middle is far beyond it.
      double sx = 0, sy = 0, sxx = 0, sxy = 0;
      for (int c = 0; c < cols; ++c)
        sx += c, sy += col_lo[size_t(c)], sxx += double(c) * c, sxy += c * col_lo[size_t(c)];
      const double slope = (cols * sxy - sx * sy) / (cols * sxx - sx * sx),
                   icpt = (sy - slope * sx) / cols;
      double chi2 = 0;
      for (int c = 0; c < cols; ++c) {
        const double r = col_lo[size_t(c)] - (icpt + slope * c);
        chi2 += r * r / (st.var_low / rows);
      }
      chi2 /= std::max(1, cols - 2);
      if (!(chi2 < 16)) {
        char b[256];
        std::snprintf(b, sizeof b,
                      "step A-150 %g mm, aluminium %g mm (pixels %d-%d, lines %d-%d): its middle "
                      "is not flat (columns spread %.1fx their noise); the wedge is not where "
                      "wedge.yaml puts it",
                      w.a150_mm[i], w.al_mm[j], p0, p1 - 1, l0, l1 - 1, std::sqrt(chi2));
        fail(dir, ": ", b);
      }
      scan.steps.push_back(st);
    }
  return scan;
}

}  // namespace rangex
