#pragma once
// The benchmarks' nearest-rank percentile (q in 0..1; 0 for no values): the value at rank q x n of the sorted values.
#include <algorithm>
#include <vector>

namespace rehearse::testing {

inline double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())))];
}

}  // namespace rehearse::testing
