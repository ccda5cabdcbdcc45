#include "pipeline/component_extreme.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <vector>

namespace rangex {

namespace {

// Union-find over the pixels switched on so far, keyed by pixel index.
class Forest {
 public:
  int add(size_t i) {
    const int id = int(parent_.size());
    index_.emplace(i, id);
    parent_.push_back(id);
    size_.push_back(1);
    return id;
  }
  int find(size_t i) const {
    const auto it = index_.find(i);
    return it == index_.end() ? -1 : root(it->second);
  }
  int unite(int a, int b) {
    a = root(a), b = root(b);
    if (a == b) return size_[size_t(a)];
    if (size_[size_t(a)] < size_[size_t(b)]) std::swap(a, b);
    parent_[size_t(b)] = a;
    return size_[size_t(a)] += size_[size_t(b)];
  }

 private:
  int root(int a) const {
    while (parent_[size_t(a)] != a) a = parent_[size_t(a)] = parent_[size_t(parent_[size_t(a)])];
    return a;
  }
  std::unordered_map<size_t, int> index_;
  mutable std::vector<int> parent_;
  std::vector<int> size_;
};

}  // namespace

double component_extreme(const float* v, const uint8_t* use, int rows, int cols, int min_pixels) {
  std::vector<size_t> px;
  for (size_t i = 0, n = size_t(rows) * cols; i < n; ++i)
    if (use[i]) px.push_back(i);
  return component_extreme(v, px, rows, cols, min_pixels);
}

double component_extreme(const float* v, std::vector<size_t>& px, int rows, int cols,
                         int min_pixels) {
  constexpr double kNone = -std::numeric_limits<double>::infinity();
  std::erase_if(px, [&](size_t i) { return !std::isfinite(v[i]); });
  if (px.empty()) return kNone;
  if (min_pixels <= 1) {
    double m = kNone;
    for (size_t i : px) m = std::max(m, double(v[i]));
    return m;
  }
  // Pixels from the highest down, joined to their switched-on neighbours, until a component
  // reaches min_pixels: the level of the pixel that completed it. Usually within the first
  // few dozen pixels, so the order is found a block at a time.
  auto higher = [&](size_t a, size_t b) { return v[a] > v[b]; };
  Forest forest;
  size_t sorted = 0;
  for (size_t k = 0; k < px.size(); ++k) {
    if (k == sorted) {
      const size_t block = std::min(px.size(), std::max<size_t>(256, 4 * sorted));
      std::partial_sort(px.begin() + long(sorted), px.begin() + long(block), px.end(), higher);
      sorted = block;
    }
    const size_t i = px[k];
    const int r = int(i / size_t(cols)), c = int(i % size_t(cols));
    int id = forest.add(i), size = 1;
    for (int dr = -1; dr <= 1; ++dr)
      for (int dc = -1; dc <= 1; ++dc) {
        const int rr = r + dr, cc = c + dc;
        if ((dr == 0 && dc == 0) || rr < 0 || cc < 0 || rr >= rows || cc >= cols) continue;
        const int other = forest.find(size_t(rr) * size_t(cols) + size_t(cc));
        if (other >= 0) size = forest.unite(id, other);
      }
    if (size >= min_pixels) return v[i];
  }
  return kNone;
}

}  // namespace rangex
