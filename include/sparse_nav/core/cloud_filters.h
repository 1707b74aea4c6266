#ifndef SPARSE_NAV_CORE_CLOUD_FILTERS_H
#define SPARSE_NAV_CORE_CLOUD_FILTERS_H

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "sparse_nav/core/types.h"

namespace sparse_nav
{
/// @brief Configuration of PointGuard.
struct PointGuardConfig
{
  /// Points with any |coordinate| above this are dropped [input units, usually m]. Guards the
  /// voxel grid and the octree against absurd values such as 1e9 from a diverged SLAM map.
  double max_abs_coordinate = 1e4;

  /// @brief Throws std::invalid_argument when a value is out of range.
  void validate() const;
};

/// @brief What PointGuard did to a cloud.
struct PointGuardStats
{
  std::size_t n_in = 0;            ///< points given
  std::size_t n_non_finite = 0;    ///< dropped because a coordinate was NaN or infinite
  std::size_t n_out_of_range = 0;  ///< dropped because |coordinate| > max_abs_coordinate
  std::size_t n_out = 0;           ///< points kept
};

/**
 * @brief Drops non-finite points and points beyond a range limit, and counts them.
 *
 * Works in any frame; the limit is in the same units as the points.
 */
class PointGuard
{
public:
  explicit PointGuard(const PointGuardConfig& config = PointGuardConfig());
  /// @brief Returns the finite points within range, in input order.
  PointList apply(const PointList& points, PointGuardStats* stats = nullptr) const;
  const PointGuardConfig& config() const { return config_; }

private:
  PointGuardConfig config_;
};

/// @brief Density filter method.
enum class DensityMethod
{
  kNone,            ///< keep every point
  kRadiusOutlier,   ///< one pass of PCL RadiusOutlierRemoval's rule, counted in a spatial hash (same result)
  kIpcl             ///< seed 000 IPCL: `ipcl_rounds` rounds of the neighbour-count rule
};

/// @brief Parses "none", "radius" or "ipcl"; throws std::invalid_argument otherwise.
DensityMethod densityMethodFromString(const std::string& name);

/// @brief Configuration of DensityFilter.
struct DensityFilterConfig
{
  DensityMethod method = DensityMethod::kRadiusOutlier;
  double radius_m = 0.3;   ///< neighbourhood radius [m]; sparse monocular walls need a wide one
  int min_neighbors = 5;   ///< a point survives iff it has >= min_neighbors other points within radius_m
  int ipcl_rounds = 2;     ///< rounds for kIpcl (removals applied at the end of each round)

  /// @brief Throws std::invalid_argument when a value is out of range.
  void validate() const;
};

/// @brief What DensityFilter did.
struct DensityFilterStats
{
  std::size_t n_in = 0;
  std::size_t n_out = 0;
  int rounds_run = 0;  ///< rounds actually run (IPCL stops early once nothing is removed)
  std::size_t n_counted = 0;  ///< points whose neighbours were counted (fewer in an update)
};

/**
 * @brief Removes isolated points: PCL RadiusOutlierRemoval, or IPCL (iterated pseudo-clustering)
 * implemented on a voxel hash with cell size radius_m (27 neighbouring cells per query).
 *
 * Units are metres (apply the SLAM scale first); any frame.
 */
class DensityFilter
{
public:
  explicit DensityFilter(const DensityFilterConfig& config = DensityFilterConfig());
  PointList apply(const PointList& points, DensityFilterStats* stats = nullptr) const;
  /// @brief Per point, 1 when apply() keeps it.
  std::vector<char> keepFlags(const PointList& points, DensityFilterStats* stats = nullptr) const;
  /**
   * @brief keepFlags(points), given the flags of an earlier cloud: with the radius rule only the
   * points within radius_m of a point that changed are counted again (a neighbour count is local);
   * IPCL's rounds cascade, so it counts every point again.
   * @param previous_index per point, its index in previous_points when it is the same point, else -1
   * @param previous_keep keepFlags(previous_points)
   */
  std::vector<char> keepFlagsUpdated(const PointList& points, const std::vector<std::int32_t>& previous_index,
                                     const PointList& previous_points, const std::vector<char>& previous_keep,
                                     DensityFilterStats* stats = nullptr) const;
  const DensityFilterConfig& config() const { return config_; }

private:
  std::vector<char> ipclFlags(const PointList& points, DensityFilterStats* stats) const;

  DensityFilterConfig config_;
};

/// @brief Configuration of VoxelFilter.
struct VoxelFilterConfig
{
  double leaf_size_m = 0.05;  ///< voxel edge [m]; each occupied voxel becomes its centroid

  /// @brief Throws std::invalid_argument when a value is out of range.
  void validate() const;
};

/// @brief What VoxelFilter did.
struct VoxelFilterStats
{
  std::size_t n_in = 0;
  std::size_t n_out = 0;
};

/**
 * @brief The voxel centroids of a cloud, kept between calls so that a cloud that changed in a few
 * points is updated in the voxels those points left or entered, and says which centroids are
 * still the ones it gave before.
 *
 * PCL's VoxelGrid has no update: it sorts every point again, and its int32 voxel index overflows
 * on wide clouds. Here each voxel keeps its count and the sums of its points in double: sums of
 * floats of one voxel are exact in double, so removing a point undoes adding it and an update
 * gives the centroids of a build from scratch, independent of the order of the points. Voxel
 * indices are 64-bit: no extent overflows them. A build from nothing gives the centroids sorted
 * by voxel (z, then y, then x index), the order PCL gives; an update touches only the voxels
 * that changed (memory traffic over every voxel cost more than the update's own work), so their
 * order is then its own. Units are metres; any frame.
 */
class IncrementalVoxelGrid
{
public:
  explicit IncrementalVoxelGrid(const VoxelFilterConfig& config = VoxelFilterConfig());

  /**
   * @brief Adds and removes points. Each removed point must be one added before, exactly; points
   * removed that no voxel holds are ignored and counted (n_unknown_removals).
   */
  void update(const PointList& added, const PointList& removed);
  /// @brief Forgets every point.
  void clear();

  /// @brief One centroid per occupied voxel: sorted by voxel after a build from nothing; an
  /// update rewrites the changed ones in place, fills the place of an emptied voxel with the last
  /// one and appends new ones.
  const PointList& centroids() const { return centroids_; }
  /// @brief Per centroid: its index in centroids() before the last update when its voxel's points
  /// are the same, else -1.
  const std::vector<std::int32_t>& previousIndex() const { return previous_index_; }
  /// @brief Centroids of the previous update that are gone or changed in the last one.
  std::size_t numDropped() const { return n_dropped_; }
  std::size_t numUnknownRemovals() const { return n_unknown_removals_; }
  const VoxelFilterConfig& config() const { return config_; }

private:
  struct Key
  {
    std::int64_t z, y, x;
    bool operator<(const Key& o) const { return z != o.z ? z < o.z : (y != o.y ? y < o.y : x < o.x); }
    bool operator==(const Key& o) const { return z == o.z && y == o.y && x == o.x; }
  };
  struct Voxel
  {
    Key key;
    double sx, sy, sz;
    std::int64_t n;
  };
  struct Entry
  {
    Key key;
    std::int32_t slot;  // -1: emptied since the index was made
  };
  Key keyOf(const Eigen::Vector3f& p) const;
  /// The voxel's place in voxels_, or -1.
  std::int32_t slotOf(const Key& key) const;
  /// Records the voxel's place; -1 forgets it.
  void setSlot(const Key& key, std::int32_t slot);

  VoxelFilterConfig config_;
  std::vector<Voxel> voxels_;  // n > 0; in key order after a build from nothing
  PointList centroids_;        // of voxels_, place by place
  std::vector<Entry> index_;   // by key: the voxels when it was made
  std::map<Key, std::int32_t> index_added_;  // voxels that came since
  std::size_t n_emptied_ = 0;  // entries of index_ with slot -1
  std::vector<std::int32_t> previous_index_;
  std::size_t n_dropped_ = 0;
  std::size_t n_unknown_removals_ = 0;
};

/**
 * @brief The voxel grid of a cloud that changes a little between calls, as SLAM map points do:
 * they keep their place in the list and new ones are appended, so the points that differ from the
 * last cloud at the same index are the ones that moved, and only their voxels change. A cloud
 * that differs in more than half its points is built from scratch. Disabled, the cloud itself is
 * the output. Units are metres; any frame.
 */
class IncrementalVoxelFilter
{
public:
  explicit IncrementalVoxelFilter(const VoxelFilterConfig& config = VoxelFilterConfig(), bool enabled = true);

  /// @brief The centroids of points (points itself when disabled), valid until the next call. The
  /// cloud is kept to compare the next one with: a caller done with it moves it in.
  const PointList& apply(PointList points);
  /// @brief Forgets the last cloud: the next one is built from scratch.
  void clear();

  /// @brief Per output point of the last apply(): its index in the output before, when it is the
  /// same point, else -1.
  const std::vector<std::int32_t>& previousIndex() const { return enabled_ ? grid_.previousIndex() : previous_index_; }
  /// @brief Input points of the last apply() that differ from the cloud before (all of them after
  /// clear() or a rebuild).
  std::size_t numChanged() const { return n_changed_; }
  /// @brief Whether the last apply() built the output from scratch.
  bool rebuilt() const { return rebuilt_; }
  bool enabled() const { return enabled_; }

private:
  bool enabled_;
  IncrementalVoxelGrid grid_;
  PointList last_points_;
  std::vector<std::int32_t> previous_index_;  // disabled only: per point, its index in the last cloud or -1
  std::size_t n_changed_ = 0;
  bool rebuilt_ = true;
  // Scratch of apply(), kept for its capacity.
  PointList added_, removed_;
};

/**
 * @brief Voxel-grid downsampling: each occupied voxel becomes the centroid of its points, sorted
 * by voxel (an IncrementalVoxelGrid built from scratch). Units are metres; any frame.
 */
class VoxelFilter
{
public:
  explicit VoxelFilter(const VoxelFilterConfig& config = VoxelFilterConfig());
  PointList apply(const PointList& points, VoxelFilterStats* stats = nullptr) const;
  const VoxelFilterConfig& config() const { return config_; }

private:
  VoxelFilterConfig config_;
};

}  // namespace sparse_nav

#endif  // SPARSE_NAV_CORE_CLOUD_FILTERS_H
