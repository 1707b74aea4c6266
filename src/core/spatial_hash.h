#ifndef SPARSE_NAV_CORE_SPATIAL_HASH_H
#define SPARSE_NAV_CORE_SPATIAL_HASH_H

// Private helper of sparse_nav_core (not installed): a uniform-grid hash of 3D points.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "sparse_nav/core/flat_key_set.h"
#include "sparse_nav/core/types.h"

namespace sparse_nav
{
struct CellKey
{
  std::int64_t x;
  std::int64_t y;
  std::int64_t z;
  bool operator==(const CellKey& o) const { return x == o.x && y == o.y && z == o.z; }
};

struct CellKeyHash
{
  std::size_t operator()(const CellKey& k) const
  {
    std::uint64_t h = static_cast<std::uint64_t>(k.x) * 0x9E3779B97F4A7C15ULL;
    h ^= static_cast<std::uint64_t>(k.y) * 0xC2B2AE3D27D4EB4FULL + (h << 6) + (h >> 2);
    h ^= static_cast<std::uint64_t>(k.z) * 0x165667B19E3779F9ULL + (h << 6) + (h >> 2);
    return static_cast<std::size_t>(h);
  }
};

/// Points bucketed in cubic cells of edge `cell`; a query visits the 27 cells around a point, so
/// every point within `cell` of the query is visited.
class SpatialHash3
{
public:
  SpatialHash3(double cell, const PointList& points) : inv_(1.0 / cell)
  {
    std::vector<CellKey> point_keys(points.size());
    CellKey lo{ 0, 0, 0 }, hi{ -1, -1, -1 };
    for (std::size_t i = 0; i < points.size(); ++i)
    {
      const CellKey k = key(points[i]);
      point_keys[i] = k;
      lo = i == 0 ? k : CellKey{ std::min(lo.x, k.x), std::min(lo.y, k.y), std::min(lo.z, k.z) };
      hi = i == 0 ? k : CellKey{ std::max(hi.x, k.x), std::max(hi.y, k.y), std::max(hi.z, k.z) };
    }
    // A room-sized cloud spans few enough cells for a dense table of cell ids over its box; the
    // 27 lookups per cell are then plain indexing instead of hashed probes (most of the density
    // filter's time). Up to 2^18 cells (1 MB) it is dense for any number of points: the floor's
    // wall normals look up 10^4 points in a room's ~10^5 cells. Otherwise cell ids go in open
    // addressing (linear probing, at most half full).
    const double box_cells = (static_cast<double>(hi.x - lo.x) + 1) * (static_cast<double>(hi.y - lo.y) + 1) *
                             (static_cast<double>(hi.z - lo.z) + 1);
    if (!points.empty() && box_cells <= std::max(8.0 * static_cast<double>(points.size()), 262144.0))
    {
      box_lo_ = lo;
      box_size_ = CellKey{ hi.x - lo.x + 1, hi.y - lo.y + 1, hi.z - lo.z + 1 };
      box_ids_.assign(static_cast<std::size_t>(box_cells), kEmpty);
      std::size_t n = 0;
      for (int iz : kOrder)
      {
        for (int iy : kOrder)
        {
          for (int ix : kOrder)
          {
            around_offsets_[n++] = (iz * box_size_.y + iy) * box_size_.x + ix;
          }
        }
      }
    }
    else
    {
      slots_.assign(openAddressingSlots(2 * points.size(), shift_), kEmpty);
    }
    std::vector<std::uint32_t> cell_of(points.size());
    for (std::size_t i = 0; i < points.size(); ++i)
    {
      const CellKey& k = point_keys[i];
      std::uint32_t& id = box_ids_.empty() ? slots_[findSlot(k)] : box_ids_[boxIndex(k)];
      if (id == kEmpty)
      {
        id = static_cast<std::uint32_t>(keys_.size());
        keys_.push_back(k);
      }
      cell_of[i] = id;
    }
    start_.assign(keys_.size() + 1, 0);
    for (std::uint32_t c : cell_of)
    {
      ++start_[c + 1];
    }
    for (std::size_t c = 1; c < start_.size(); ++c)
    {
      start_[c] += start_[c - 1];
    }
    items_.resize(points.size());
    std::vector<std::uint32_t> fill(start_.begin(), start_.end() - 1);
    for (std::size_t i = 0; i < points.size(); ++i)
    {
      items_[fill[cell_of[i]]++] = static_cast<std::uint32_t>(i);
    }
  }

  CellKey key(const Eigen::Vector3f& p) const
  {
    return CellKey{ static_cast<std::int64_t>(std::floor(p.x() * inv_)),
                    static_cast<std::int64_t>(std::floor(p.y() * inv_)),
                    static_cast<std::int64_t>(std::floor(p.z() * inv_)) };
  }

  /// Calls visit(index) for the points in the 27 cells around p until visit returns false; p's own
  /// cell comes first, so a count that stops early mostly needs one lookup.
  template <typename Visit>
  void forEachNear(const Eigen::Vector3f& p, Visit visit) const
  {
    cellsAround(key(p), [&](std::uint32_t cell) {
      for (std::uint32_t k = start_[cell]; k < start_[cell + 1]; ++k)
      {
        if (!visit(items_[k]))
        {
          return false;
        }
      }
      return true;
    });
  }

  /**
   * @brief Per point of the points the hash was built on, 1 when at least k others lie within
   * radius (<= the cell edge) of it. Counts stop at k. The points are visited cell by cell, so the
   * 27 cells around are looked up once per cell rather than once per point.
   */
  std::vector<char> hasNeighbours(const PointList& points, float radius, std::size_t k) const
  {
    std::vector<char> result(points.size(), 0);
    const float r2 = radius * radius;
    std::vector<std::uint32_t> around;  // cell ids, the points' own first
    for (std::uint32_t cell = 0; cell < keys_.size(); ++cell)
    {
      around.clear();
      cellsAround(keys_[cell], [&](std::uint32_t id) {
        around.push_back(id);
        return true;
      });
      for (std::uint32_t a = start_[cell]; a < start_[cell + 1]; ++a)
      {
        const std::uint32_t i = items_[a];
        const Eigen::Vector3f& p = points[i];
        std::size_t count = 0;
        for (std::size_t n = 0; n < around.size() && count < k; ++n)
        {
          for (std::uint32_t b = start_[around[n]]; b < start_[around[n] + 1] && count < k; ++b)
          {
            const std::uint32_t j = items_[b];
            count += j != i && (points[j] - p).squaredNorm() <= r2;
          }
        }
        result[i] = count >= k;
      }
    }
    return result;
  }

private:
  /// Calls visit(cell id) for the occupied cells among the 27 around c, c first, until it returns false.
  template <typename Visit>
  void cellsAround(const CellKey& c, Visit visit) const
  {
    if (!box_ids_.empty() && c.x > box_lo_.x && c.y > box_lo_.y && c.z > box_lo_.z && c.x < box_lo_.x + box_size_.x - 1 &&
        c.y < box_lo_.y + box_size_.y - 1 && c.z < box_lo_.z + box_size_.z - 1)
    {
      // All 27 lie inside the dense box: each at a fixed offset from c's place in it.
      const std::uint32_t* at = box_ids_.data() + boxIndex(c);
      for (const std::ptrdiff_t offset : around_offsets_)
      {
        const std::uint32_t id = at[offset];
        if (id != kEmpty && !visit(id))
        {
          return;
        }
      }
      return;
    }
    for (int iz : kOrder)
    {
      for (int iy : kOrder)
      {
        for (int ix : kOrder)
        {
          const std::uint32_t id = cellId(CellKey{ c.x + ix, c.y + iy, c.z + iz });
          if (id != kEmpty && !visit(id))
          {
            return;
          }
        }
      }
    }
  }

  std::size_t slotOf(const CellKey& k) const
  {
    return fibonacciSlot(static_cast<std::uint64_t>(CellKeyHash()(k)), shift_);
  }

  /// The slot holding key k, or the empty slot where its probe ends (where k would go).
  std::size_t findSlot(const CellKey& k) const
  {
    std::size_t s = slotOf(k);
    while (slots_[s] != kEmpty && !(keys_[slots_[s]] == k))
    {
      s = (s + 1) & (slots_.size() - 1);
    }
    return s;
  }

  /// The id of the cell with key k, or kEmpty when no point lies in it.
  std::uint32_t cellId(const CellKey& k) const
  {
    if (box_ids_.empty())
    {
      return slots_[findSlot(k)];
    }
    const std::uint64_t dx = static_cast<std::uint64_t>(k.x - box_lo_.x), dy = static_cast<std::uint64_t>(k.y - box_lo_.y),
                        dz = static_cast<std::uint64_t>(k.z - box_lo_.z);
    if (dx >= static_cast<std::uint64_t>(box_size_.x) || dy >= static_cast<std::uint64_t>(box_size_.y) ||
        dz >= static_cast<std::uint64_t>(box_size_.z))
    {
      return kEmpty;
    }
    return box_ids_[boxIndex(k)];
  }

  /// Index of k in box_ids_; k inside the box.
  std::size_t boxIndex(const CellKey& k) const
  {
    return static_cast<std::size_t>(((k.z - box_lo_.z) * box_size_.y + (k.y - box_lo_.y)) * box_size_.x +
                                    (k.x - box_lo_.x));
  }

  static constexpr std::uint32_t kEmpty = 0xFFFFFFFFu;
  static constexpr int kOrder[3] = { 0, -1, 1 };  // around a cell: itself first on each axis
  double inv_;
  int shift_ = 0;
  std::vector<std::uint32_t> slots_;  // cell id per slot, or kEmpty (hashed mode)
  CellKey box_lo_{ 0, 0, 0 }, box_size_{ 0, 0, 0 };
  std::vector<std::uint32_t> box_ids_;  // cell id per cell of the points' box, or kEmpty (dense mode)
  std::ptrdiff_t around_offsets_[27] = {};  // dense mode: the 27 cells around one, in cellsAround()'s order
  std::vector<std::uint32_t> start_;
  std::vector<std::uint32_t> items_;
  std::vector<CellKey> keys_;  // per cell id
};

}  // namespace sparse_nav

#endif  // SPARSE_NAV_CORE_SPATIAL_HASH_H
