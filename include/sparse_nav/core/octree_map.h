#ifndef SPARSE_NAV_CORE_OCTREE_MAP_H
#define SPARSE_NAV_CORE_OCTREE_MAP_H

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "sparse_nav/core/flat_key_set.h"
#include "sparse_nav/core/types.h"

namespace octomap
{
class OcTree;
}

namespace sparse_nav
{
/// @brief Configuration of OctreeMap. All values in the map frame, metres.
struct OctreeMapConfig
{
  double resolution_m = 0.05;  ///< smallest voxel edge [m]
  double max_range_m = -1.0;   ///< rays longer than this are truncated (endpoint not marked); < 0: no limit
  /// Free space is ray-cast in voxels of this edge [m]: resolution_m times a power of two (the
  /// octree stores them as coarse leaves). Equal to resolution_m casts at full resolution; 4x
  /// visits 4x fewer voxels per ray and 64x fewer voxels per volume.
  double free_space_resolution_m = 0.2;
  double prob_hit = 0.7;       ///< OctoMap hit probability
  double prob_miss = 0.4;      ///< OctoMap miss probability (free space along rays)

  /// @brief Throws std::invalid_argument when a value is out of range.
  void validate() const;
};

/// @brief What an insertion did.
struct OctreeInsertStats
{
  std::size_t n_inserted = 0;      ///< points inserted as occupied endpoints (new or already known)
  std::size_t n_new_voxels = 0;    ///< endpoint voxels seen for the first time: only these cast rays
  std::size_t n_rays = 0;          ///< rays cast (one per new endpoint free-space voxel and camera)
  std::size_t n_free_voxels = 0;   ///< free-space voxels updated
  std::size_t n_out_of_range = 0;  ///< dropped: non-finite or outside the octree's key range
  bool origin_ok = true;           ///< false when the sensor origin was outside the key range (nothing inserted)
};

/// @brief Outcome of save/load: ok, or a message saying what went wrong.
struct IoStatus
{
  bool ok = false;
  std::string message;
};

/// @brief State of a position in the octree.
enum class VoxelState
{
  kUnknown,
  kFree,
  kOccupied
};

/**
 * @brief OctoMap occupancy octree in the map frame (z up, metres), with free space ray-cast from
 * the camera positions.
 *
 * Insertion is incremental: the tree remembers which endpoint voxels it has seen, and only points
 * in voxels it has not seen yet cast rays, so re-inserting a map whose points mostly stayed put
 * costs little. Rays are cast in free_space_resolution_m voxels, one ray per coarse endpoint voxel
 * and camera, and a coarse voxel holding any endpoint of the insertion is never marked free by it
 * (OctoMap's "occupied wins" rule at that resolution). Endpoints are hits at full resolution.
 *
 * The octree's 16-bit keys cover +-32768 voxels around the origin (+-1638.4 m at 5 cm); points
 * outside that range, and non-finite points, are dropped and counted instead of reaching OctoMap.
 * save()/load() use OctoMap's binary .bt format; load() never throws and leaves the current tree
 * unchanged when the file is missing or corrupt.
 */
class OctreeMap
{
public:
  explicit OctreeMap(const OctreeMapConfig& config = OctreeMapConfig());
  ~OctreeMap();
  OctreeMap(const OctreeMap&) = delete;
  OctreeMap& operator=(const OctreeMap&) = delete;

  /// @brief Inserts points as occupied and marks the voxels on the rays from sensor_origin free.
  /// @param points endpoints in the map frame [m]
  /// @param sensor_origin camera position in the map frame [m]
  OctreeInsertStats insert(const PointList& points, const Eigen::Vector3d& sensor_origin);

  /**
   * @brief Inserts points whose rays start at several camera positions.
   * @param points endpoints in the map frame [m]
   * @param origins camera positions in the map frame [m]
   * @param origin_of_point index into origins for each point (same size as points)
   * @param also_held optional: points inserted before that are still part of the cloud [m]. Their
   *        coarse voxels are kept from being freed, as if they were in `points`, without being
   *        looked up again: an update passes its new points in `points` and the rest here, and
   *        gets what inserting the whole cloud gives.
   */
  OctreeInsertStats insert(const PointList& points, const std::vector<Eigen::Vector3d>& origins,
                           const std::vector<std::size_t>& origin_of_point, const PointList* also_held = nullptr);

  /// @brief State of the voxel containing position (map frame, m).
  VoxelState query(const Eigen::Vector3d& position) const;

  /**
   * @brief States of the voxels containing positions (map frame, m), one per position, each the
   * same as query(position). One descent over the positions in Morton order, resuming each from
   * the deepest node it shares with the one before, instead of one from the root per position.
   */
  std::vector<VoxelState> query(const PointList& positions) const;

  /// @brief Centres of occupied leaf voxels [m] (one per leaf; coarse leaves give their centre).
  PointList occupiedCenters() const;

  /**
   * @brief Marks the cells of a 2D grid window whose column contains a free leaf voxel with z in
   * [z_min_m, z_max_m] and no occupied one.
   * @param free_mask row-major width x height, set to 1 for free cells (others untouched)
   */
  void markFreeColumns(double origin_x_m, double origin_y_m, double resolution_m, int width, int height,
                       double z_min_m, double z_max_m, std::vector<std::uint8_t>& free_mask) const;

  /// @brief Largest |coordinate| the octree can represent [m].
  double maxCoordinate() const;
  std::size_t numLeafNodes() const;
  void clear();
  /// @brief Writes the tree to `path` (.bt). Never throws.
  IoStatus save(const std::string& path) const;
  /// @brief Replaces the tree by the one in `path` (.bt); on any error the tree is unchanged. Never throws.
  IoStatus load(const std::string& path);

  const OctreeMapConfig& config() const { return config_; }

private:
  bool inRange(const Eigen::Vector3d& p) const;
  void resetTree();

  OctreeMapConfig config_;
  std::unique_ptr<octomap::OcTree> tree_;
  unsigned free_levels_ = 0;  // free_space_resolution_m = resolution_m * 2^free_levels_
  FlatKeySet inserted_;  // packed keys of the endpoint voxels inserted so far
};

}  // namespace sparse_nav

#endif  // SPARSE_NAV_CORE_OCTREE_MAP_H
