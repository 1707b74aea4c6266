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
  double distance_threshold_m = 0.1;   ///< inlier distance of the floor plane [m]; monocular floors are noisy
  int max_iterations = 500;            ///< RANSAC iterations per plane
  /// Candidate planes extracted before choosing; sparse floors come after slices through dense walls.
  int max_planes = 12;
  /// A candidate counts as well supported when it has at least this fraction of the inliers of the
  /// best-supported candidate; the lowest well-supported candidate along up_axis is the floor.
  double min_relative_support = 0.1;
  std::size_t min_inliers = 30;        ///< a floor needs at least this many inliers
  double min_inlier_fraction = 0.02;   ///< ... and at least this fraction of the (fitted) points
  /// The floor's lower side is the quantile of the heights along a candidate normal that leaves
  /// this fraction of the points under it (outliers below the floor).
  double low_quantile = 0.01;
  /// A floor has many more points on it than just under it: inliers >= this times the points in
  /// the slab of twice distance_threshold_m beneath. Tells a floor from the bottom of a random cloud.
  double min_contrast = 3.0;
  /// A floor has (almost) nothing under it: a candidate with more than this fraction of the points
  /// further than below_margin_m beneath it is rejected.
  double max_below_fraction = 0.1;
  double below_margin_m = 0.1;  ///< [m]
  double tilt_step_deg = 0.5;          ///< finest step of the normal search [deg]
  double wall_radius_m = 0.3;          ///< neighbourhood of the wall-normal estimate [m]
  /// A fitted floor whose normal is further than this from the walls' up is taken for a slab of
  /// wall bottoms; the floor is then perpendicular to the walls at their lower envelope [deg].
  /// Generous: monocular depth noise fans walls out by 1-3 deg, so the walls' up is no finer.
  double max_wall_disagreement_deg = 5.0;
  std::size_t max_fit_points = 10000;  ///< larger clouds are subsampled (fixed stride)

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
 * @brief Finds the floor: the lower envelope of the cloud along the normal, within max_tilt_deg of
 * the nominal up axis, that holds the most points.
 *
 * Monocular SLAM sees little of the floor (1-5 % of the points in the simulator's worlds), and the
 * point density grows from the floor up the walls, so the floor is no peak of any height histogram
 * and sample consensus prefers slanted planes through the wall bottoms. The floor is where the
 * points start: for each candidate normal (a coarse-to-fine search over the cone), the slab of
 * 2 * distance_threshold_m above the low_quantile of the heights is counted, and the normal whose
 * slab holds the most points wins (a wrong normal touches the floor only along one edge). The
 * plane is then refitted by least squares to the points within distance_threshold_m, twice, with
 * the second pass at half the distance. A floor needs min_inliers, min_inlier_fraction, contrast
 * against the slab beneath it and few points below it. The envelope cannot see past its cone, so
 * an envelope floor is checked by sample consensus in a 45 deg cone on a small sample: a plane
 * beyond the limit with clearly more points means the floor is tilted too much. Only when the
 * envelope is rejected does sample consensus (PCL, up to max_planes planes, the lowest
 * well-supported one) find the floor. When
 * the best floor-like plane within 45 deg is tilted beyond max_tilt_deg and holds more points than
 * every one within the limit, the result is "no floor" (the floor is tilted too much) rather than
 * a guess. Deterministic. Give it the cloud before any density filter: isolated floor points are
 * what it needs.
 */
class FloorDetector
{
public:
  explicit FloorDetector(const FloorDetectorConfig& config = FloorDetectorConfig());
  /// @param points cloud in the SLAM frame [m]
  FloorResult detect(const PointList& points) const;
  const FloorDetectorConfig& config() const { return config_; }

private:
  FloorResult detectByConsensus(const PointList& points) const;
  FloorResult detectByEnvelope(const PointList& points) const;
  FloorResult tiltedBeyondTheLimit(const PointList& points, const FloorResult& envelope) const;

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
/// @brief The same into `out` (resized; its capacity is reused).
void transformPoints(const PointList& points, const Eigen::Isometry3d& transform, PointList& out);

}  // namespace sparse_nav

#endif  // SPARSE_NAV_CORE_FLOOR_PLANE_H
