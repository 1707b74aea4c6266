#ifndef SPARSE_NAV_CORE_GRID_PIPELINE_H
#define SPARSE_NAV_CORE_GRID_PIPELINE_H

#include <cstddef>
#include <map>
#include <memory>
#include <string>

#include <Eigen/Geometry>

#include "sparse_nav/core/cloud_filters.h"
#include "sparse_nav/core/floor_plane.h"
#include "sparse_nav/core/grid_builder.h"
#include "sparse_nav/core/ground_mapper.h"
#include "sparse_nav/core/octree_map.h"
#include "sparse_nav/core/types.h"

namespace sparse_nav
{
/// @brief Configuration of GridPipeline; metric values apply after scaling by metres_per_unit.
struct GridPipelineConfig
{
  /// Metres per SLAM unit. Monocular SLAM has no metric scale: pass the known scale (slam/scale,
  /// camera height, known motions); 1 treats SLAM units as metres.
  double metres_per_unit = 1.0;
  PointGuardConfig guard;
  bool voxel_enabled = true;
  VoxelFilterConfig voxel;
  /// Floor, alignment, octree, bands and free-space filter. keep_floor and align_to_floor are true
  /// here: the first floor found defines the map frame (a moving floor would shift the whole map).
  GroundMapperConfig ground;
  GridBuilderConfig grid;

  /// @brief Validates this and every nested Config; throws std::invalid_argument.
  void validate() const;
};

/// @brief Outcome of one GridPipeline::process call.
struct GridPipelineResult
{
  bool ok = false;
  std::string status;  ///< summary, or what went wrong when !ok
  std::size_t n_points = 0;
  std::size_t n_changed_points = 0;  ///< points not at the same place in the list as in the last cloud
  PointGuardStats guard;
  DensityFilterStats density;  ///< counts of GroundMapper's density filter
  VoxelFilterStats voxel;
  FloorResult floor;
  Eigen::Isometry3d slam_to_map = Eigen::Isometry3d::Identity();  ///< SLAM frame (scaled) -> map
  OctreeInsertStats octree;
  std::size_t n_floor_band = 0;    ///< points removed as floor (z < floor_clearance_m)
  std::size_t n_ceiling_band = 0;  ///< points removed as ceiling (z > ceiling_height_m)
  std::size_t n_freed = 0;         ///< band points removed because the octree proved their voxel free
  std::size_t n_obstacles = 0;
  GridUpdate grid;
  std::map<std::string, double> stages_ms;  ///< wall time per stage [ms]
  double total_ms = 0.0;
};

/**
 * @brief The perception chain from SLAM map points to an occupancy grid: guard, scale, voxel grid,
 * then GroundMapper (floor plane, density filter, alignment to the z-up map frame, octree with
 * free space ray-cast from the cameras, floor/ceiling band removal, free-space filter), then
 * GridBuilder (alpha shapes and rasterisation, with dirty-tile incremental updates). The nodelets
 * cloud_filter (guard, voxel grid), ground_mapper and grid_builder run the same three stages. Calling process() again
 * with a changed cloud is an incremental update: the points that differ from the last cloud at the
 * same place in the list (SLAM map points keep their order; new ones are appended) change only
 * their voxels; GroundMapper, given which voxels stayed, counts density again only around the
 * changed ones, casts octree rays and counts rays passing under obstacles only for what changed;
 * GridBuilder takes the obstacles and rays that went and came and recomputes only the tiles
 * within reach of them. Each of these gives what a rebuild from scratch on the same cloud gives. Never throws on bad data;
 * problems are reported in the result.
 */
class GridPipeline
{
public:
  explicit GridPipeline(const GridPipelineConfig& config = GridPipelineConfig());
  ~GridPipeline();

  /**
   * @param slam_points map points in the SLAM frame [SLAM units]
   * @param camera_positions camera positions in the SLAM frame [SLAM units]; free-space rays start
   *        at the nearest one. Empty: the SLAM origin (the first camera of ORB-SLAM) is used.
   */
  GridPipelineResult process(const PointList& slam_points, const PointList& camera_positions);

  /// @brief Forgets the floor, the octree and the grid.
  void reset();

  const OccupancyGrid& grid() const { return builder_.grid(); }
  const GridBuilder& builder() const { return builder_; }
  /// @brief The octree, or nullptr when octree_enabled is false.
  OctreeMap* octree() { return ground_.octree(); }
  const GroundMapper& ground() const { return ground_; }
  bool hasFloor() const { return ground_.hasFloor(); }
  const FloorPlane& floor() const { return ground_.floor().plane; }
  const GridPipelineConfig& config() const { return config_; }

private:
  /// After an error midway: the next cloud is taken whole, not as a change of this one.
  void forgetLastCloud();

  GridPipelineConfig config_;
  PointGuard guard_;
  IncrementalVoxelFilter voxel_;  // of the guarded, scaled cloud
  bool ground_saw_last_cloud_ = false;  // GroundMapper's last input is voxel_'s last output
  bool builder_saw_last_ground_ = false;  // GridBuilder's last input is GroundMapper's last output
  // Scratch of process(), kept for its capacity.
  PointList2D obstacles_xy_;
  GroundMapper ground_;
  GridBuilder builder_;
};

}  // namespace sparse_nav

#endif  // SPARSE_NAV_CORE_GRID_PIPELINE_H
