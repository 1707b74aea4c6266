#ifndef SPARSE_NAV_CORE_GROUND_MAPPER_H
#define SPARSE_NAV_CORE_GROUND_MAPPER_H

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "sparse_nav/core/cloud_filters.h"
#include "sparse_nav/core/floor_plane.h"
#include "sparse_nav/core/grid_builder.h"
#include "sparse_nav/core/octree_map.h"
#include "sparse_nav/core/ray_pass_count.h"
#include "sparse_nav/core/types.h"

namespace sparse_nav
{
/// @brief Configuration of GroundMapper. Metric values in metres, heights along the floor normal.
struct GroundMapperConfig
{
  FloorDetectorConfig floor;
  /// true: detect the floor until one is found, then keep it. false: detect it in every cloud and
  /// keep the last one found when a cloud shows none.
  bool keep_floor = true;
  /// true: the output frame is alignToFloor(floor) (z up, floor at z = 0), for SLAM-frame input.
  /// false: the output frame is the input frame (input already in the z-up map frame).
  bool align_to_floor = true;
  /// Removes isolated points after the floor is found and before the octree: monocular floors are
  /// sparse, so a density filter ahead of the floor search strips the floor it looks for.
  DensityFilterConfig density;
  double floor_clearance_m = 0.15;  ///< points lower than this above the floor are floor [m]
  double ceiling_height_m = 2.2;    ///< points higher than this above the floor are ceiling [m]
  bool octree_enabled = true;
  OctreeMapConfig octree;
  /// Drop obstacle points whose octree voxel the camera rays have proven free (stray points
  /// smeared into doorways by monocular depth noise). Needs the octree.
  bool free_space_filter = true;
  /// Drop obstacle points whose x-y cell (clear_cell_m) at least this many camera rays pass
  /// through (rays ending in the cell not counted) below the top of the cell's obstacle points and
  /// at most clear_height_tolerance_m under their bottom: a point the camera saw past is depth
  /// noise, such as one smeared into a doorway. Rays over a low box do not clear it. 0: off.
  int clear_hit_min_rays = 3;
  double clear_cell_m = 0.05;             ///< cell of that count [m]; the grid's resolution
  double clear_height_tolerance_m = 0.4;  ///< rays this far below a cell's lowest point still count [m]
  /// A ray counts only where at least this fraction of its length is still ahead: monocular depth
  /// noise grows with range, so a ray to a point just behind another on a wall seen at a grazing
  /// angle says nothing about it (0.25 keeps the walls of a hallway).
  double clear_range_margin = 0.25;
  /// The count runs over a dense box of cells around the obstacle points; beyond this many cells
  /// (a cloud hundreds of metres wide) it is skipped and the status says so.
  std::size_t clear_max_cells = 1U << 25;

  /// @brief Throws std::invalid_argument when a value is out of range.
  void validate() const;
};

/// @brief Outcome of GroundMapper::process; every point set is in the output frame.
struct GroundMapperResult
{
  bool ok = false;
  std::string status;  ///< summary, or what went wrong when !ok
  FloorResult floor;   ///< the floor in use (found = false only when there is none yet)
  bool floor_changed = false;  ///< the output frame moved (a new floor with align_to_floor): start over
  std::string floor_warning;   ///< why this cloud showed no floor when the last one found is kept
  Eigen::Isometry3d to_output = Eigen::Isometry3d::Identity();  ///< input frame -> output frame
  std::vector<Eigen::Vector3d> cameras;  ///< camera positions used, output frame [m]
  DensityFilterStats density;  ///< the density filter's counts (the points it kept go on)
  PointList obstacles;     ///< points between the floor band and the ceiling band, not proven free
  PointList floor_points;  ///< points within floor_clearance_m of the floor plane
  /// Per point, the part of its ray from the nearest camera inside the band (x-y). Empty when
  /// `incremental`: an update needs only the rays that changed (GroundMapper::rays() makes all).
  std::vector<FreeRay> rays;
  std::size_t n_floor_band = 0;    ///< points below floor_clearance_m
  std::size_t n_ceiling_band = 0;  ///< points above ceiling_height_m
  std::size_t n_freed = 0;         ///< band points dropped because their voxel is free
  std::size_t n_passed = 0;        ///< band points dropped because clear_hit_min_rays rays passed them
  OctreeInsertStats octree;
  std::map<std::string, double> stages_ms;  ///< "floor", "density", "align", "octree", "slice" [ms]
  /// True when this call continued from the last one through previous_index: the change lists
  /// below then say how obstacles (x-y) and rays differ from the last call's.
  bool incremental = false;
  PointList2D obstacles_removed_xy;
  PointList2D obstacles_added_xy;
  std::vector<FreeRay> rays_removed;
  std::vector<FreeRay> rays_added;
};

/**
 * @brief The ground stage of the perception chain: floor plane, density filter, alignment, OctoMap octree with
 * free space ray-cast from the cameras, floor and ceiling bands measured from the floor plane,
 * the free-space filter of obstacle points, the count of rays passing under them
 * (clear_hit_min_rays), and the free rays inside the band.
 *
 * build_grid (through GridPipeline) and the ground_mapper nodelet both run this object, so the
 * same cloud gives the same obstacles. The octree is kept across calls; only points in voxels it
 * has not seen cast rays (OctreeMap::insert). Given previous_index, process() continues from
 * its last call when the floor and the cameras are the same (else it starts over): points that
 * stayed keep their camera, band and octree state, only the new ones
 * are looked up and inserted, the ray count changes by them alone (RayPassCount::update), and the
 * result says how its obstacles and rays differ from the last ones (for GridBuilder's update).
 */
class GroundMapper
{
public:
  explicit GroundMapper(const GroundMapperConfig& config = GroundMapperConfig());
  ~GroundMapper();

  /**
   * @param input guarded (and voxel-filtered) cloud in the input frame [m], outliers included
   * @param cameras camera positions in the input frame [m]; rays start at the nearest one. Empty:
   *        the input frame's origin (the first ORB-SLAM camera).
   * @param previous_index optional: per input point, its index in the previous call's input when
   *        it is the same point, else -1 (IncrementalVoxelGrid::previousIndex). The density filter
   *        then counts again only around the points that changed.
   */
  GroundMapperResult process(const PointList& input, const std::vector<Eigen::Vector3d>& cameras,
                             const std::vector<std::int32_t>* previous_index = nullptr);

  /// @brief Forgets the floor and the octree.
  void reset();

  /// @brief The rays GroundMapperResult::rays lists for the last process() that got through (the
  /// same rays, in the order of that call's points), also when that call was incremental.
  std::vector<FreeRay> rays() const;

  bool hasFloor() const { return has_floor_; }
  const FloorResult& floor() const { return floor_; }
  /// @brief The octree, or nullptr when octree_enabled is false.
  OctreeMap* octree() { return octree_.get(); }
  const OctreeMap* octree() const { return octree_.get(); }
  const GroundMapperConfig& config() const { return config_; }

private:
  GroundMapperConfig config_;
  FloorDetector detector_;
  DensityFilter density_;
  std::unique_ptr<OctreeMap> octree_;
  bool has_floor_ = false;
  FloorResult floor_;
  // Kinds of the points that pass the density filter.
  static constexpr char kFloorBand = 0, kCeilingBand = 1, kFreed = 2, kCandidate = 3;

  RayPassCount pass_count_;
  PointList last_input_;          // the previous call's input
  std::vector<char> last_keep_;   // its density flags; empty when the filter did not run on it
  std::vector<std::int32_t> last_dense_of_input_;  // per point of last_input_, its index among those kept, or -1
  std::vector<Eigen::Vector3d> last_cameras_;      // the cameras of the last call, input frame
  std::vector<Eigen::Vector3d> last_cameras_out_;  // ... in the output frame
  std::vector<double> last_camera_h_;              // ... their heights above the floor
  // Per point kept by the last call that got through: kind, obstacle or not, camera, output-frame
  // position [m], height above the floor [m]; enough to take back its ray, candidacy and obstacle.
  std::vector<char> last_kind_;
  std::vector<char> last_obstacle_;
  std::vector<std::size_t> last_camera_;
  PointList last_out_;
  std::vector<double> last_h_;
  // Scratch of process(), kept for its capacity.
  std::vector<std::uint32_t> kept_;
  PointList out_;
  std::vector<std::int32_t> dense_of_input_;
  std::vector<std::int32_t> dense_previous_;
  std::vector<std::size_t> nearest_;
  std::vector<double> heights_;
  std::vector<char> kind_;
  std::vector<char> obstacle_;
  std::vector<PassCandidate> candidates_;
  std::vector<std::size_t> candidate_index_;
};

}  // namespace sparse_nav

#endif  // SPARSE_NAV_CORE_GROUND_MAPPER_H
