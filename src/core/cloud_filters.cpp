#include "sparse_nav/core/cloud_filters.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>

#include "radix_sort.h"
#include "spatial_hash.h"

namespace sparse_nav
{
namespace
{
/// The points whose keep flag is set, in their order.
PointList keptPoints(const PointList& points, const std::vector<char>& keep)
{
  PointList out;
  out.reserve(static_cast<std::size_t>(std::count(keep.begin(), keep.end(), 1)));
  for (std::size_t i = 0; i < points.size(); ++i)
  {
    if (keep[i])
    {
      out.push_back(points[i]);
    }
  }
  return out;
}
}  // namespace


void PointGuardConfig::validate() const
{
  if (!(max_abs_coordinate > 0.0) || !std::isfinite(max_abs_coordinate))
  {
    throw std::invalid_argument("PointGuardConfig: max_abs_coordinate must be finite and > 0");
  }
}

PointGuard::PointGuard(const PointGuardConfig& config) : config_(config)
{
  config_.validate();
}

PointList PointGuard::apply(const PointList& points, PointGuardStats* stats) const
{
  PointGuardStats s;
  s.n_in = points.size();
  PointList out;
  out.reserve(points.size());
  const float limit = static_cast<float>(config_.max_abs_coordinate);
  for (const auto& p : points)
  {
    if (!p.allFinite())
    {
      ++s.n_non_finite;
      continue;
    }
    if (std::abs(p.x()) > limit || std::abs(p.y()) > limit || std::abs(p.z()) > limit)
    {
      ++s.n_out_of_range;
      continue;
    }
    out.push_back(p);
  }
  s.n_out = out.size();
  if (stats)
  {
    *stats = s;
  }
  return out;
}


DensityMethod densityMethodFromString(const std::string& name)
{
  if (name == "none")
  {
    return DensityMethod::kNone;
  }
  if (name == "radius")
  {
    return DensityMethod::kRadiusOutlier;
  }
  if (name == "ipcl")
  {
    return DensityMethod::kIpcl;
  }
  throw std::invalid_argument("density method must be one of none, radius, ipcl; got '" + name + "'");
}

void DensityFilterConfig::validate() const
{
  if (!(radius_m > 0.0) || !std::isfinite(radius_m))
  {
    throw std::invalid_argument("DensityFilterConfig: radius_m must be finite and > 0");
  }
  if (min_neighbors < 0)
  {
    throw std::invalid_argument("DensityFilterConfig: min_neighbors must be >= 0");
  }
  if (ipcl_rounds < 1)
  {
    throw std::invalid_argument("DensityFilterConfig: ipcl_rounds must be >= 1");
  }
}

DensityFilter::DensityFilter(const DensityFilterConfig& config) : config_(config)
{
  config_.validate();
}

PointList DensityFilter::apply(const PointList& points, DensityFilterStats* stats) const
{
  return keptPoints(points, keepFlags(points, stats));
}

std::vector<char> DensityFilter::keepFlags(const PointList& points, DensityFilterStats* stats) const
{
  DensityFilterStats s;
  s.n_in = points.size();
  std::vector<char> keep;
  if (config_.method == DensityMethod::kNone || config_.min_neighbors == 0 || points.empty())
  {
    keep.assign(points.size(), 1);
  }
  else if (config_.method == DensityMethod::kIpcl)
  {
    keep = ipclFlags(points, &s);
    s.n_counted = points.size();
  }
  else
  {
    // PCL's RadiusOutlierRemoval rule (keep points with >= min_neighbors others within radius_m),
    // counted in a uniform hash that stops at min_neighbors: a k-d tree radius search returns every
    // neighbour, which in dense clouds costs ten times more.
    const SpatialHash3 hash(config_.radius_m, points);
    keep = hash.hasNeighbours(points, static_cast<float>(config_.radius_m), static_cast<std::size_t>(config_.min_neighbors));
    s.rounds_run = 1;
    s.n_counted = points.size();
  }
  s.n_out = static_cast<std::size_t>(std::count(keep.begin(), keep.end(), 1));
  if (stats)
  {
    *stats = s;
  }
  return keep;
}

std::vector<char> DensityFilter::keepFlagsUpdated(const PointList& points, const std::vector<std::int32_t>& previous_index,
                                                  const PointList& previous_points, const std::vector<char>& previous_keep,
                                                  DensityFilterStats* stats) const
{
  const bool consistent = previous_index.size() == points.size() && previous_keep.size() == previous_points.size();
  if (!consistent || config_.method != DensityMethod::kRadiusOutlier || config_.min_neighbors == 0)
  {
    return keepFlags(points, stats);
  }
  // Cells of radius_m: a point's neighbours lie in the 27 cells around its own. The points that
  // entered or left mark their cells; only points in the 27 cells around a marked one can change
  // their count, and those counts need the points of the 125 cells around.
  const double inv = 1.0 / config_.radius_m;
  constexpr std::int64_t kHalf = std::int64_t{ 1 } << 20;
  auto cellOf = [inv](const Eigen::Vector3f& p) {
    return Eigen::Array3d(std::floor(p.x() * inv), std::floor(p.y() * inv), std::floor(p.z() * inv));
  };
  auto packed = [](const Eigen::Array3d& c) {
    return static_cast<std::uint64_t>(static_cast<std::int64_t>(c.x()) + kHalf) << 42 |
           static_cast<std::uint64_t>(static_cast<std::int64_t>(c.y()) + kHalf) << 21 |
           static_cast<std::uint64_t>(static_cast<std::int64_t>(c.z()) + kHalf);
  };
  std::vector<Eigen::Array3d> marked;
  std::vector<char> referenced(previous_points.size(), 0);
  for (std::size_t i = 0; i < points.size(); ++i)
  {
    const std::int32_t k = previous_index[i];
    if (k < 0 || static_cast<std::size_t>(k) >= previous_points.size() || referenced[static_cast<std::size_t>(k)])
    {
      if (k >= 0)
      {
        return keepFlags(points, stats);  // not a correspondence
      }
      marked.push_back(cellOf(points[i]));
    }
    else
    {
      referenced[static_cast<std::size_t>(k)] = 1;
    }
  }
  for (std::size_t k = 0; k < previous_points.size(); ++k)
  {
    if (!referenced[k])
    {
      marked.push_back(cellOf(previous_points[k]));
    }
  }
  std::vector<char> keep(points.size(), 0);
  for (std::size_t i = 0; i < points.size(); ++i)
  {
    keep[i] = previous_index[i] >= 0 ? previous_keep[static_cast<std::size_t>(previous_index[i])] : 0;
  }
  DensityFilterStats s;
  s.n_in = points.size();
  s.rounds_run = 1;
  if (!marked.empty())
  {
    Eigen::Array3d lo = marked.front(), hi = lo;
    for (const auto& c : marked)
    {
      lo = lo.min(c);
      hi = hi.max(c);
    }
    if ((lo.abs().maxCoeff() + 2.0) >= static_cast<double>(kHalf) || (hi.abs().maxCoeff() + 2.0) >= static_cast<double>(kHalf))
    {
      return keepFlags(points, stats);
    }
    // Many changed points share a cell: each cell is widened once.
    FlatKeySet near1, near2, seen;
    for (const auto& c : marked)
    {
      if (!seen.insert(packed(c)))
      {
        continue;
      }
      for (int dx = -2; dx <= 2; ++dx)
      {
        for (int dy = -2; dy <= 2; ++dy)
        {
          for (int dz = -2; dz <= 2; ++dz)
          {
            const std::uint64_t key = packed(c + Eigen::Array3d(dx, dy, dz));
            near2.insert(key);
            if (std::abs(dx) <= 1 && std::abs(dy) <= 1 && std::abs(dz) <= 1)
            {
              near1.insert(key);
            }
          }
        }
      }
    }
    lo -= 2.0;
    hi += 2.0;
    // The box of those cells in metres, widened by a cell: most points fail it before their cell is taken.
    const Eigen::Array3f lo_m = ((lo - 1.0) * config_.radius_m).cast<float>(), hi_m = ((hi + 2.0) * config_.radius_m).cast<float>();
    PointList support;
    std::vector<std::size_t> support_index;
    std::vector<char> recount;
    for (std::size_t i = 0; i < points.size(); ++i)
    {
      const Eigen::Array3f p = points[i].array();
      if ((p < lo_m).any() || (p > hi_m).any())
      {
        continue;
      }
      const Eigen::Array3d c = cellOf(points[i]);
      if ((c < lo).any() || (c > hi).any() || !near2.contains(packed(c)))
      {
        continue;
      }
      support.push_back(points[i]);
      support_index.push_back(i);
      recount.push_back(near1.contains(packed(c)) ? 1 : 0);
    }
    const SpatialHash3 hash(config_.radius_m, support);
    const std::vector<char> counted =
        hash.hasNeighbours(support, static_cast<float>(config_.radius_m), static_cast<std::size_t>(config_.min_neighbors));
    for (std::size_t j = 0; j < support.size(); ++j)
    {
      if (recount[j])
      {
        keep[support_index[j]] = counted[j];
        ++s.n_counted;
      }
    }
  }
  s.n_out = static_cast<std::size_t>(std::count(keep.begin(), keep.end(), 1));
  if (stats)
  {
    *stats = s;
  }
  return keep;
}

std::vector<char> DensityFilter::ipclFlags(const PointList& points, DensityFilterStats* stats) const
{
  const double r = config_.radius_m;
  std::vector<char> keep(points.size(), 1);
  std::vector<std::size_t> alive_index(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
  {
    alive_index[i] = i;
  }
  PointList alive = points;
  for (int round = 0; round < config_.ipcl_rounds && !alive.empty(); ++round)
  {
    ++stats->rounds_run;
    const SpatialHash3 hash(r, alive);
    const std::vector<char> round_keep =
        hash.hasNeighbours(alive, static_cast<float>(r), static_cast<std::size_t>(config_.min_neighbors));
    const std::size_t n_keep = static_cast<std::size_t>(std::count(round_keep.begin(), round_keep.end(), 1));
    if (n_keep == alive.size())
    {
      break;
    }
    PointList next;
    std::vector<std::size_t> next_index;
    for (std::size_t j = 0; j < alive.size(); ++j)
    {
      if (round_keep[j])
      {
        next.push_back(alive[j]);
        next_index.push_back(alive_index[j]);
      }
      else
      {
        keep[alive_index[j]] = 0;
      }
    }
    alive.swap(next);
    alive_index.swap(next_index);
  }
  return keep;
}

void VoxelFilterConfig::validate() const
{
  if (!(leaf_size_m > 0.0) || !std::isfinite(leaf_size_m))
  {
    throw std::invalid_argument("VoxelFilterConfig: leaf_size_m must be finite and > 0");
  }
}

IncrementalVoxelGrid::IncrementalVoxelGrid(const VoxelFilterConfig& config) : config_((config.validate(), config))
{
}

IncrementalVoxelGrid::Key IncrementalVoxelGrid::keyOf(const Eigen::Vector3f& p) const
{
  const double inv = 1.0 / config_.leaf_size_m;
  return Key{ static_cast<std::int64_t>(std::floor(static_cast<double>(p.z()) * inv)),
              static_cast<std::int64_t>(std::floor(static_cast<double>(p.y()) * inv)),
              static_cast<std::int64_t>(std::floor(static_cast<double>(p.x()) * inv)) };
}

void IncrementalVoxelGrid::clear()
{
  voxels_.clear();
  centroids_.clear();
  index_.clear();
  index_added_.clear();
  n_emptied_ = 0;
  previous_index_.clear();
  n_dropped_ = 0;
  n_unknown_removals_ = 0;
}

void IncrementalVoxelGrid::update(const PointList& added, const PointList& removed)
{
  // Change c < removed.size() is a removal, the rest additions.
  const std::size_t n_removed = removed.size(), n = n_removed + added.size();
  auto pointOf = [&](std::size_t c) -> const Eigen::Vector3f& {
    return c < n_removed ? removed[c] : added[c - n_removed];
  };
  // The changes in voxel order. When the batch's voxel indices, offset to its minimum, and the
  // change's own index pack into 64 bits (10^6 changes spanning 800 m on every axis at 5 cm still
  // do), each change is one 8-byte item, packed key above the change's index, radix-sorted by the
  // key stably; the walk below then compares packed keys instead of computing keys again. Otherwise
  // a comparison sort of the changes by their keys.
  auto bits = [](std::uint64_t span) {
    int b = 0;
    while (b < 63 && (span >> b) != 0)
    {
      ++b;
    }
    return b;
  };
  // A key grows with each coordinate: the keys of the coordinates' minima and maxima bound them.
  Eigen::Array3f min_p = Eigen::Array3f::Zero(), max_p = min_p;
  for (std::size_t c = 0; c < n; ++c)
  {
    const Eigen::Array3f p = pointOf(c).array();
    min_p = c == 0 ? p : min_p.min(p);
    max_p = c == 0 ? p : max_p.max(p);
  }
  const Key lo = keyOf(min_p.matrix()), hi = keyOf(max_p.matrix());
  const int bx = bits(static_cast<std::uint64_t>(hi.x - lo.x)), by = bits(static_cast<std::uint64_t>(hi.y - lo.y)),
            bz = bits(static_cast<std::uint64_t>(hi.z - lo.z)), bc = bits(n > 0 ? n - 1 : 0);
  const bool packs = bx + by + bz + bc <= 64;
  // Shifts of 64 are undefined: a field of no bits, always 0, is left out.
  auto field = [](std::uint64_t value, int width, int shift) { return width == 0 ? std::uint64_t{ 0 } : value << shift; };
  auto low = [](std::uint64_t value, int width) { return width == 0 ? std::uint64_t{ 0 } : value & (~std::uint64_t{ 0 } >> (64 - width)); };
  std::vector<std::uint64_t> sorted;  // packed: key above change
  std::vector<Key> keys;              // otherwise: per change, its key
  std::vector<std::uint32_t> order;   // and the changes sorted by it
  if (packs)
  {
    sorted.resize(n);
    for (std::size_t c = 0; c < n; ++c)
    {
      const Key k = keyOf(pointOf(c));
      sorted[c] = field(static_cast<std::uint64_t>(k.z - lo.z), bz, bc + bx + by) |
                  field(static_cast<std::uint64_t>(k.y - lo.y), by, bc + bx) |
                  field(static_cast<std::uint64_t>(k.x - lo.x), bx, bc) | c;
    }
    radixSortBy(sorted, [bc](std::uint64_t e) { return e >> bc; });
  }
  else
  {
    keys.resize(n);
    order.resize(n);
    for (std::size_t c = 0; c < n; ++c)
    {
      keys[c] = keyOf(pointOf(c));
      order[c] = static_cast<std::uint32_t>(c);
    }
    std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return keys[a] < keys[b]; });
  }
  // The j-th change in voxel order, whether it lies in the same voxel as the i-th, and its voxel.
  auto changeAt = [&](std::size_t j) { return packs ? static_cast<std::size_t>(low(sorted[j], bc)) : order[j]; };
  auto sameVoxel = [&](std::size_t i, std::size_t j) {
    return packs ? (sorted[i] ^ sorted[j]) >> bc == 0 : keys[order[i]] == keys[order[j]];
  };
  auto keyAt = [&](std::size_t j) {
    if (!packs)
    {
      return keys[order[j]];
    }
    const std::uint64_t code = sorted[j] >> bc;
    return Key{ lo.z + static_cast<std::int64_t>(bx + by == 64 ? 0 : low(code >> (bx + by), bz)),
                lo.y + static_cast<std::int64_t>(low(code >> bx, by)), lo.x + static_cast<std::int64_t>(low(code, bx)) };
  };

  n_dropped_ = 0;
  n_unknown_removals_ = 0;
  // Walks the changes voxel by voxel: calls apply(key, sum added, count added, sum removed, count removed).
  auto forEachVoxel = [&](auto apply) {
    for (std::size_t j = 0; j < n;)
    {
      const std::size_t first = j;
      // Sums of this voxel's additions and removals: exact in double, so their order does not matter.
      Eigen::Vector3d add = Eigen::Vector3d::Zero(), rem = Eigen::Vector3d::Zero();
      std::int64_t n_add = 0, n_rem = 0;
      do
      {
        const std::size_t c = changeAt(j);
        const Eigen::Vector3d p = pointOf(c).cast<double>();
        if (c < n_removed)
        {
          rem += p;
          ++n_rem;
        }
        else
        {
          add += p;
          ++n_add;
        }
        ++j;
      } while (j < n && sameVoxel(first, j));
      apply(keyAt(first), add, n_add, rem, n_rem);
    }
  };
  auto centroidOf = [](const Voxel& v) {
    const double count = static_cast<double>(v.n);
    return Eigen::Vector3f(static_cast<float>(v.sx / count), static_cast<float>(v.sy / count), static_cast<float>(v.sz / count));
  };

  if (voxels_.empty())
  {
    // From nothing: the voxels in key order, and the index over them as it stands.
    voxels_.reserve(added.size());
    centroids_.reserve(added.size());
    forEachVoxel([&](const Key& key, const Eigen::Vector3d& add, std::int64_t n_add, const Eigen::Vector3d&, std::int64_t n_rem) {
      n_unknown_removals_ += static_cast<std::size_t>(n_rem);
      if (n_add > 0)
      {
        voxels_.push_back(Voxel{ key, add.x(), add.y(), add.z(), n_add });
        centroids_.push_back(centroidOf(voxels_.back()));
      }
    });
    previous_index_.assign(voxels_.size(), -1);
    index_.resize(voxels_.size());
    for (std::size_t i = 0; i < voxels_.size(); ++i)
    {
      index_[i] = Entry{ voxels_[i].key, static_cast<std::int32_t>(i) };
    }
    index_added_.clear();
    n_emptied_ = 0;
    return;
  }

  // In place: changed voxels are rewritten where they are, an emptied one takes the last voxel
  // into its place, and new ones come at the end; the rest is not touched.
  previous_index_.resize(voxels_.size());
  for (std::size_t i = 0; i < voxels_.size(); ++i)
  {
    previous_index_[i] = static_cast<std::int32_t>(i);
  }
  forEachVoxel([&](const Key& key, const Eigen::Vector3d& add, std::int64_t n_add, const Eigen::Vector3d& rem,
                   std::int64_t n_rem) {
    const std::int32_t slot = slotOf(key);
    if (slot < 0)
    {
      n_unknown_removals_ += static_cast<std::size_t>(n_rem);
      if (n_add > 0)
      {
        voxels_.push_back(Voxel{ key, add.x(), add.y(), add.z(), n_add });
        centroids_.push_back(centroidOf(voxels_.back()));
        previous_index_.push_back(-1);
        setSlot(key, static_cast<std::int32_t>(voxels_.size() - 1));
      }
      return;
    }
    Voxel& v = voxels_[static_cast<std::size_t>(slot)];
    // More removals than points held: the caller removed points it never added; ignore them all.
    if (n_rem > v.n)
    {
      n_unknown_removals_ += static_cast<std::size_t>(n_rem);
    }
    else
    {
      v.sx -= rem.x();
      v.sy -= rem.y();
      v.sz -= rem.z();
      v.n -= n_rem;
    }
    v.sx += add.x();
    v.sy += add.y();
    v.sz += add.z();
    v.n += n_add;
    ++n_dropped_;
    if (v.n > 0)
    {
      centroids_[static_cast<std::size_t>(slot)] = centroidOf(v);
      previous_index_[static_cast<std::size_t>(slot)] = -1;
      return;
    }
    setSlot(key, -1);
    const std::size_t last = voxels_.size() - 1;
    if (static_cast<std::size_t>(slot) != last)
    {
      voxels_[static_cast<std::size_t>(slot)] = voxels_[last];
      centroids_[static_cast<std::size_t>(slot)] = centroids_[last];
      previous_index_[static_cast<std::size_t>(slot)] = previous_index_[last];
      setSlot(voxels_[static_cast<std::size_t>(slot)].key, slot);
    }
    voxels_.pop_back();
    centroids_.pop_back();
    previous_index_.pop_back();
  });
  // Emptied entries and keys added since the index was made are looked up the slow way: once
  // they are a quarter of it, it is made again, by one merge of the two sorted parts.
  if (4 * (n_emptied_ + index_added_.size()) > index_.size())
  {
    std::vector<Entry> merged;
    merged.reserve(voxels_.size());
    auto it = index_added_.begin();
    for (const Entry& e : index_)
    {
      for (; it != index_added_.end() && it->first < e.key; ++it)
      {
        merged.push_back(Entry{ it->first, it->second });
      }
      if (e.slot >= 0)
      {
        merged.push_back(e);
      }
    }
    for (; it != index_added_.end(); ++it)
    {
      merged.push_back(Entry{ it->first, it->second });
    }
    index_.swap(merged);
    index_added_.clear();
    n_emptied_ = 0;
  }
}

std::int32_t IncrementalVoxelGrid::slotOf(const Key& key) const
{
  const auto it = std::lower_bound(index_.begin(), index_.end(), key, [](const Entry& e, const Key& k) { return e.key < k; });
  if (it != index_.end() && it->key == key)
  {
    return it->slot;  // -1 when emptied since; then it is not in index_added_ either
  }
  const auto found = index_added_.find(key);
  return found == index_added_.end() ? -1 : found->second;
}

void IncrementalVoxelGrid::setSlot(const Key& key, std::int32_t slot)
{
  const auto it = std::lower_bound(index_.begin(), index_.end(), key, [](const Entry& e, const Key& k) { return e.key < k; });
  if (it != index_.end() && it->key == key)
  {
    if (it->slot >= 0 && slot < 0)
    {
      ++n_emptied_;
    }
    else if (it->slot < 0 && slot >= 0)
    {
      --n_emptied_;
    }
    it->slot = slot;
    return;
  }
  if (slot < 0)
  {
    index_added_.erase(key);
  }
  else
  {
    index_added_[key] = slot;
  }
}

IncrementalVoxelFilter::IncrementalVoxelFilter(const VoxelFilterConfig& config, bool enabled)
  : enabled_(enabled), grid_(config)
{
}

void IncrementalVoxelFilter::clear()
{
  grid_.clear();
  last_points_.clear();
}

const PointList& IncrementalVoxelFilter::apply(PointList points)
{
  added_.clear();
  removed_.clear();
  const std::size_t common = std::min(points.size(), last_points_.size());
  const std::size_t appended = points.size() - common;
  // Removing and adding most of the points costs twice a build, and a build keeps voxel order: once
  // more than half the cloud is known to have changed, the lists of changes are not made further.
  auto mostlyChanged = [&](std::size_t n_added) { return 2 * n_added > points.size(); };
  rebuilt_ = common == 0 || mostlyChanged(appended);
  if (!enabled_)
  {
    previous_index_.assign(points.size(), -1);
  }
  for (std::size_t i = 0; i < common && !rebuilt_; ++i)
  {
    if (!(points[i] == last_points_[i]))
    {
      removed_.push_back(last_points_[i]);
      added_.push_back(points[i]);
      rebuilt_ = mostlyChanged(added_.size() + appended);
    }
    else if (!enabled_)
    {
      previous_index_[i] = static_cast<std::int32_t>(i);
    }
  }
  if (rebuilt_)
  {
    std::fill(previous_index_.begin(), previous_index_.end(), -1);
  }
  else
  {
    removed_.insert(removed_.end(), last_points_.begin() + static_cast<std::ptrdiff_t>(common), last_points_.end());
    added_.insert(added_.end(), points.begin() + static_cast<std::ptrdiff_t>(common), points.end());
  }
  n_changed_ = rebuilt_ ? points.size() : added_.size();
  last_points_ = std::move(points);
  if (!enabled_)
  {
    return last_points_;
  }
  if (rebuilt_)
  {
    grid_.clear();
    grid_.update(last_points_, PointList());
  }
  else
  {
    grid_.update(added_, removed_);
  }
  return grid_.centroids();
}

VoxelFilter::VoxelFilter(const VoxelFilterConfig& config) : config_(config)
{
  config_.validate();
}

PointList VoxelFilter::apply(const PointList& points, VoxelFilterStats* stats) const
{
  IncrementalVoxelGrid grid(config_);
  grid.update(points, PointList());
  if (stats)
  {
    stats->n_in = points.size();
    stats->n_out = grid.centroids().size();
  }
  return grid.centroids();
}

}  // namespace sparse_nav
