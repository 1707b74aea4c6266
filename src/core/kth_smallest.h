#ifndef SPARSE_NAV_CORE_KTH_SMALLEST_H
#define SPARSE_NAV_CORE_KTH_SMALLEST_H

// Private helper of sparse_nav_core (not installed).

#include <algorithm>
#include <cstddef>
#include <iterator>
#include <vector>

namespace sparse_nav
{
/// The value std::nth_element would put at index k (0-based; k < values.size()), from a max-heap of
/// the k + 1 smallest. For a low quantile (the floor search's 1 %) almost every value costs one
/// comparison with the heap's top, where nth_element on a copy of all values was most of the
/// floor search's time.
inline double kthSmallest(const std::vector<double>& values, std::size_t k)
{
  std::vector<double> lowest(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k + 1));
  std::make_heap(lowest.begin(), lowest.end());
  for (std::size_t i = k + 1; i < values.size(); ++i)
  {
    if (values[i] < lowest.front())
    {
      std::pop_heap(lowest.begin(), lowest.end());
      lowest.back() = values[i];
      std::push_heap(lowest.begin(), lowest.end());
    }
  }
  return lowest.front();
}

}  // namespace sparse_nav

#endif  // SPARSE_NAV_CORE_KTH_SMALLEST_H
