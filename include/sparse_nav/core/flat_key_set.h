#ifndef SPARSE_NAV_CORE_FLAT_KEY_SET_H
#define SPARSE_NAV_CORE_FLAT_KEY_SET_H

#include <cstddef>
#include <cstdint>
#include <vector>

namespace sparse_nav
{
/// @brief Slots of an open-addressing table for at least min_slots: the smallest power of two
/// >= min_slots and >= 16; shift is set to 64 - log2(slots), for fibonacciSlot.
inline std::size_t openAddressingSlots(std::size_t min_slots, int& shift)
{
  std::size_t capacity = 16;
  int log2_capacity = 4;
  while (capacity < min_slots)
  {
    capacity *= 2;
    ++log2_capacity;
  }
  shift = 64 - log2_capacity;
  return capacity;
}

/// @brief The slot a probe for hash starts at: the top bits of its Fibonacci scramble.
inline std::size_t fibonacciSlot(std::uint64_t hash, int shift)
{
  return static_cast<std::size_t>((hash * 0x9E3779B97F4A7C15ULL) >> shift);
}

/**
 * @brief A set of 64-bit keys in one flat array (open addressing, linear probing, at most half
 * full). Every key but kEmptyKey can be stored.
 *
 * OctreeMap tests every endpoint of every insertion against the voxels it has seen: with
 * std::unordered_set each new key cost a node allocation, and the set was most of the endpoint
 * pass (~5 ms per 10^5 points).
 */
class FlatKeySet
{
public:
  static constexpr std::uint64_t kEmptyKey = ~std::uint64_t{ 0 };

  /// @brief Adds key; true when it was not in the set. key must not be kEmptyKey.
  bool insert(std::uint64_t key)
  {
    if (2 * (size_ + 1) > slots_.size())
    {
      grow(2 * (size_ + 1));
    }
    std::size_t s = slotOf(key);
    while (slots_[s] != kEmptyKey)
    {
      if (slots_[s] == key)
      {
        return false;
      }
      s = (s + 1) & (slots_.size() - 1);
    }
    slots_[s] = key;
    ++size_;
    return true;
  }

  bool contains(std::uint64_t key) const
  {
    if (slots_.empty())
    {
      return false;
    }
    for (std::size_t s = slotOf(key); slots_[s] != kEmptyKey; s = (s + 1) & (slots_.size() - 1))
    {
      if (slots_[s] == key)
      {
        return true;
      }
    }
    return false;
  }

  /// @brief Hints the processor to fetch the slot where key's probe starts (a lookup soon after
  /// then finds it in cache); changes nothing.
  void prefetch(std::uint64_t key) const
  {
    if (!slots_.empty())
    {
      __builtin_prefetch(&slots_[slotOf(key)]);
    }
  }

  /// @brief Makes room for n keys in all, so that inserting up to n rehashes at most once, here.
  void reserve(std::size_t n)
  {
    if (2 * n > slots_.size())
    {
      grow(2 * n);
    }
  }

  std::size_t size() const { return size_; }
  void clear()
  {
    slots_.clear();
    size_ = 0;
    shift_ = 64;
  }

private:
  std::size_t slotOf(std::uint64_t key) const { return fibonacciSlot(key, shift_); }

  /// Rehashes into openAddressingSlots(min_slots) slots.
  void grow(std::size_t min_slots)
  {
    std::vector<std::uint64_t> old(openAddressingSlots(min_slots, shift_), kEmptyKey);
    old.swap(slots_);
    size_ = 0;
    for (std::uint64_t key : old)
    {
      if (key != kEmptyKey)
      {
        std::size_t s = slotOf(key);
        while (slots_[s] != kEmptyKey)
        {
          s = (s + 1) & (slots_.size() - 1);
        }
        slots_[s] = key;
        ++size_;
      }
    }
  }

  std::vector<std::uint64_t> slots_;  // keys, or kEmptyKey
  std::size_t size_ = 0;
  int shift_ = 64;
};

}  // namespace sparse_nav

#endif  // SPARSE_NAV_CORE_FLAT_KEY_SET_H
