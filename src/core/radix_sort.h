#ifndef SPARSE_NAV_CORE_RADIX_SORT_H
#define SPARSE_NAV_CORE_RADIX_SORT_H

// Private helper of sparse_nav_core (not installed): LSD radix sort of 64-bit keys.

#include <cstddef>
#include <cstdint>
#include <vector>

namespace sparse_nav
{
/**
 * @brief Sorts items by key(item) (a 64-bit key) ascending, stably: least-significant-digit radix
 * sort, 11 bits per pass, over only the bits in which the keys differ. The core sorts packed cell
 * keys (Morton codes, ray and cell keys) whose high bits are mostly equal; on ~10^5 of them
 * boost's spreadsort, which ends in comparison sorts of small bins, took twice as long (~2 ms
 * against ~1 ms).
 */
template <typename T, typename Key>
void radixSortBy(std::vector<T>& items, Key key)
{
  if (items.size() < 2)
  {
    return;
  }
  std::uint64_t differ = 0;
  const std::uint64_t first = key(items.front());
  for (const T& item : items)
  {
    differ |= key(item) ^ first;
  }
  constexpr int kDigitBits = 11;
  constexpr std::size_t kBuckets = std::size_t{ 1 } << kDigitBits;
  std::vector<T> buffer;  // made at the first pass: keys that are all equal need none
  for (int shift = 0; shift < 64 && (differ >> shift) != 0; shift += kDigitBits)
  {
    if (((differ >> shift) & (kBuckets - 1)) == 0)
    {
      continue;  // every key has the same digit here
    }
    buffer.resize(items.size());
    std::vector<std::size_t> start(kBuckets + 1, 0);
    for (const T& item : items)
    {
      ++start[((key(item) >> shift) & (kBuckets - 1)) + 1];
    }
    for (std::size_t b = 1; b <= kBuckets; ++b)
    {
      start[b] += start[b - 1];
    }
    for (const T& item : items)
    {
      buffer[start[(key(item) >> shift) & (kBuckets - 1)]++] = item;
    }
    items.swap(buffer);
  }
}

/// @brief Sorts keys ascending (radixSortBy with the key itself).
inline void radixSort(std::vector<std::uint64_t>& keys)
{
  radixSortBy(keys, [](std::uint64_t k) { return k; });
}

}  // namespace sparse_nav

#endif  // SPARSE_NAV_CORE_RADIX_SORT_H
