#ifndef SPARSE_NAV_CORE_FLOOR_PLANE_H
#define SPARSE_NAV_CORE_FLOOR_PLANE_H

#include <cstddef>
#include <string>

#include <Eigen/Geometry>

#include "sparse_nav/core/types.h"

namespace sparse_nav
{
/// @brief Parses an axis name ("x", "-x", "+y", "-y", "z", "-z") into a unit vector; throws
/// std::invalid_argument otherwise.
Eigen::Vector3d axisFromString(const std::string& name);

/// @brief Configuration of FloorDetector. Distances in metres (after scaling), in the SLAM frame.
struct FloorDetectorConfig
{
  /// Nominal up direction in the input (SLAM) frame. Raw ORB-SLAM worlds are the first camera's
  /// optical frame (y down), hence (0, -1, 0); use (0, 0, 1) for clouds that are already z-up.
  Eigen::Vector3d up_axis = Eigen::Vector3d(0.0, -1.0, 0.0);
  double max_tilt_deg = 15.0;          ///< largest angle between the floor normal and up_axis [deg]
  double distance_threshold_m = 0.03;  ///< RANSAC inlier distance [m]
  int max_iterations = 500;            ///< RANSAC iterations per plane
  std::size_t min_inliers = 30;        ///< a candidate plane needs at least this many inliers
  double min_inlier_fraction = 0.02;   ///< ... and at least this fraction of the (fitted) points
  /// A candidate counts as well supported when it has at least this fraction of the inliers of the
  /// best-supported candidate; the lowest well-supported candidate along up_axis is the floor.
  double min_relative_support = 0.1;
  /// A floor has (almost) nothing under it: a candidate with more than this fraction of the points
  /// further than below_margin_m beneath it is rejected (a plane cutting through walls, a table top).
  double max_below_fraction = 0.1;
  double below_margin_m = 0.1;  ///< [m]
  int max_planes = 4;                  ///< candidate planes extracted before choosing
  std::size_t max_fit_points = 30000;  ///< larger clouds are subsampled (fixed stride) for RANSAC

  /// @brief Throws std::invalid_argument when a value is out of range.
  void validate() const;
};

/// @brief A plane n . p + d = 0 in the SLAM frame, with n a unit vector on the up_axis side.
struct FloorPlane
{
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< unit normal, pointing up (SLAM frame)
  double d = 0.0;              ///< offset [m]: points on the plane satisfy normal . p + d = 0
  double tilt_deg = 0.0;       ///< angle between normal and the nominal up axis [deg]
  std::size_t n_inliers = 0;   ///< inliers among the points used for fitting
  double below_fraction = 0.0; ///< fraction of the fitted points more than below_margin_m under the plane
  /// @brief Height of the plane along its normal [m] (-d).
  double height() const { return -d; }
};

/// @brief Result of FloorDetector::detect: a floor, or the reason there is none.
struct FloorResult
{
  bool found = false;
  FloorPlane plane;             ///< valid when found
  std::string reason;           ///< empty when found; otherwise why no floor was accepted
  /// Tilt of the best-supported floor-like plane within 45 deg of the up axis [deg], or NaN when
  /// there is none; tells a too-small max_tilt_deg from a cloud without any floor.
  double best_plane_tilt_deg = 0.0;
  std::size_t n_candidates = 0;  ///< planes within max_tilt_deg that were considered
};

/**
 * @brief Finds the floor: the lowest well-supported plane whose normal is within max_tilt_deg of
 * the nominal up axis, by PCL sample consensus (SACMODEL_PERPENDICULAR_PLANE, RANSAC).
 *
 * Planes are extracted one after another (inliers removed each time); the least-squares refit of a
 * plane may leave the RANSAC cone by up to 0.5 deg and is still accepted. Walls are excluded by the
 * tilt limit, planes with many points beneath them (ceilings, table tops, slabs cutting through
 * walls) are rejected, and the lowest well-supported remaining candidate is the floor. When the
 * best-supported floor-like plane within 45 deg is tilted beyond max_tilt_deg and has more support
 * than every candidate, the result is "no floor" (the floor is tilted too much) rather than a guess. The RANSAC
 * seed is PCL's fixed one, so results are deterministic.
 */
class FloorDetector
{
public:
  explicit FloorDetector(const FloorDetectorConfig& config = FloorDetectorConfig());
  /// @param points cloud in the SLAM frame [m]
  FloorResult detect(const PointList& points) const;
  const FloorDetectorConfig& config() const { return config_; }

private:
  FloorDetectorConfig config_;
};

/**
 * @brief Rigid transform from the SLAM frame to a z-up map frame with the floor at z = 0.
 *
 * The rotation is the minimal one taking the floor normal onto +z (so the heading is kept), followed
 * by a translation along z that puts the floor plane at z = 0.
 */
Eigen::Isometry3d alignToFloor(const FloorPlane& plane);

/// @brief Applies a rigid transform to every point.
PointList transformPoints(const PointList& points, const Eigen::Isometry3d& transform);

}  // namespace sparse_nav

#endif  // SPARSE_NAV_CORE_FLOOR_PLANE_H
