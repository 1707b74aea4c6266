#ifndef SPARSE_NAV_CORE_CLOUD_FILTERS_H
#define SPARSE_NAV_CORE_CLOUD_FILTERS_H

#include <cstddef>
#include <string>

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
  const DensityFilterConfig& config() const { return config_; }

private:
  PointList applyIpcl(const PointList& points, DensityFilterStats* stats) const;
  PointList applyRadiusOutlier(const PointList& points) const;

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
  std::size_t n_chunks = 1;      ///< PCL VoxelGrid calls; > 1 when the int32 index guard split the cloud
  bool overflow_guarded = false; ///< true when the cloud's extent would overflow PCL's int32 voxel index
};

/**
 * @brief Voxel-grid downsampling with PCL VoxelGrid, guarded against its int32 index overflow.
 *
 * PCL refuses (and returns the input unchanged) when (dx * dy * dz) voxels exceed INT32_MAX. This
 * class then splits the cloud into blocks of at most 1024^3 voxels aligned to multiples of the leaf,
 * downsamples each non-empty block with PCL, and reports it in VoxelFilterStats; the result is the
 * same set of voxel centroids PCL would give without the limit. Units are metres; any frame.
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
