#ifndef SPARSE_NAV_CORE_LINE_FEATURES_H
#define SPARSE_NAV_CORE_LINE_FEATURES_H

#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "sparse_nav/core/types.h"

namespace sparse_nav
{
/**
 * @brief A planar range scan with sensor_msgs/LaserScan conventions, ROS-free.
 *
 * Beam i points at angle_min_rad + i * angle_increment_rad (counter-clockwise, radians, x forward)
 * in the scan frame; ranges are metres. 0, NaN, +Inf and values outside [range_min_m,
 * range_max_m] are "no return".
 */
struct RangeScan
{
  double angle_min_rad = 0.0;
  double angle_max_rad = 0.0;        ///< angle of the last beam [rad]
  double angle_increment_rad = 0.0;  ///< > 0 [rad]
  double range_min_m = 0.0;
  double range_max_m = std::numeric_limits<double>::infinity();
  std::vector<float> ranges;

  /// @brief Empty when the fields are consistent; otherwise what is wrong (no beams, a non-finite
  /// or non-positive increment, angle_max not matching angle_min + (n - 1) * increment, ...).
  std::string check() const;
  /// @brief True when the beams cover a full turn (the last beam is next to the first one).
  bool fullCircle() const;
};

/// @brief A planar pose: position [m] and heading [rad] in some fixed frame.
struct Pose2D
{
  double x_m = 0.0;
  double y_m = 0.0;
  double yaw_rad = 0.0;
};

/// @brief Configuration of virtualScan. Heights in the cloud's frame (map: z up, floor at 0).
struct VirtualScanConfig
{
  int n_beams = 360;            ///< beams over a full turn, the first at -pi
  double min_height_m = 0.1;    ///< points below are ignored [m]
  double max_height_m = 2.0;    ///< points above are ignored [m]
  double range_min_m = 0.1;     ///< nearer points are ignored [m]
  double range_max_m = 10.0;    ///< farther points are ignored [m]

  /// @brief Throws std::invalid_argument when a value is out of range.
  void validate() const;
};

/**
 * @brief A 360-degree scan around `pose` from a z-up point cloud, like pointcloud_to_laserscan:
 * every finite point in the height band falls into its bearing bin, and the bin keeps the nearest
 * horizontal distance. Bins without a point are +Inf. Bearings are relative to pose.yaw_rad.
 */
RangeScan virtualScan(const PointList& points, const Pose2D& pose, const VirtualScanConfig& config);

/// @brief A directed wall: the free side it was seen from is on the left of start -> end.
struct ScanWall
{
  Eigen::Vector2d start = Eigen::Vector2d::Zero();  ///< [m]
  Eigen::Vector2d end = Eigen::Vector2d::Zero();    ///< [m]
  std::size_t n_points = 0;  ///< scan points the line was fitted to
  double rms_m = 0.0;        ///< RMS orthogonal residual of those points [m]
  std::size_t first_index = 0;  ///< first and last point in the extractor's ordered point list
  std::size_t last_index = 0;

  double length() const { return (end - start).norm(); }
  Eigen::Vector2d direction() const { return (end - start).normalized(); }
};

/**
 * @brief An open door: the gap from the end of wall_before to the start of wall_after, either in
 * one wall line or at the far end of a recess whose side walls face each other. The jambs lie
 * half a beam beyond the walls' last returns (on the walls' lines), which halves the bias of the
 * width.
 */
struct ScanDoor
{
  Eigen::Vector2d start = Eigen::Vector2d::Zero();  ///< jamb at the end of wall_before [m]
  Eigen::Vector2d end = Eigen::Vector2d::Zero();    ///< jamb at the start of wall_after [m]
  std::size_t wall_before = 0;
  std::size_t wall_after = 0;

  Eigen::Vector2d center() const { return 0.5 * (start + end); }
  double width() const { return (end - start).norm(); }
};

/**
 * @brief Corner types of seed 002 §3.1, seen from the robot. kInner: the corner points at the robot
 * (the inside of a turn, e.g. a box corner or the protruding corner of an L-shaped hallway);
 * kOuter: the corner points away (a room corner); kPotential: two walls whose lines meet near,
 * but not at, their observed ends, or across a break in the scan (the corner itself is hidden,
 * beyond a gap, or one wall passes behind the other).
 */
enum class CornerType : std::uint8_t
{
  kInner = 0,
  kOuter = 1,
  kPotential = 2
};

/// @brief "inner", "outer" or "potential".
const char* cornerTypeName(CornerType type);

/// @brief The three distances of seed 002 §3.1 for a corner and a missing leg A-B.
struct CornerDistances
{
  double robot_corner_m = 0.0;  ///< robot to corner
  double robot_leg_m = 0.0;     ///< robot to the line through A and B (the missing leg)
  double corner_leg_m = 0.0;    ///< corner to that line
};

/// @brief The distances of `robot` and `corner` to the missing leg through `a` and `b` [m].
CornerDistances cornerDistances(const Eigen::Vector2d& robot, const Eigen::Vector2d& corner,
                                const Eigen::Vector2d& a, const Eigen::Vector2d& b);

/**
 * @brief Seed 002's Karnaugh map: with p = (r-c < r-l), q = (r-c < c-l), s = (r-l < c-l), the corner
 * is inner iff p and not s; the two combinations that cannot occur in a plane do not reach here.
 */
CornerType classifyCorner(const CornerDistances& d);

/// @brief Two walls meeting at `point`: the end of wall_in is the start of wall_out (seed 002 §1.2.1).
struct ScanCorner
{
  Eigen::Vector2d point = Eigen::Vector2d::Zero();  ///< [m]
  std::size_t wall_in = 0;
  std::size_t wall_out = 0;
  CornerType type = CornerType::kPotential;
  double angle_deg = 0.0;  ///< angle between the two walls' lines, in (0, 180) [deg]
  CornerDistances distances;
};

/// @brief Two facing lists of nearly parallel walls (indices into ScanFeatures::walls).
struct ScanCorridor
{
  std::vector<std::size_t> side_a;
  std::vector<std::size_t> side_b;
  double width_m = 0.0;   ///< distance between the two sides' lines [m]
  double length_m = 0.0;  ///< length over which both sides are seen [m]
  Eigen::Vector2d axis_start = Eigen::Vector2d::Zero();  ///< centre line of that overlap [m]
  Eigen::Vector2d axis_end = Eigen::Vector2d::Zero();
};

/// @brief Everything extracted from one scan, in the scan's frame (the sensor at the origin).
struct ScanFeatures
{
  bool ok = false;
  std::string reason;  ///< why the scan was refused (ok false), or empty
  std::vector<ScanWall> walls;
  std::vector<ScanDoor> doors;
  std::vector<ScanCorner> corners;
  std::vector<ScanCorridor> corridors;
  PointList2D points;             ///< valid scan points in processing order [m]
  std::size_t n_ruptures = 0;     ///< beams without a usable return
  std::size_t n_breakpoints = 0;  ///< adaptive breakpoints between consecutive valid points
  std::size_t n_segments = 0;     ///< lines after the iterative end-point fit, before merging
};

/// @brief Configuration of LineFeatureExtractor. Distances in metres, angles in degrees.
struct LineFeatureConfig
{
  double min_range_m = 0.02;  ///< returns at or below are ruptures (0 = no echo) [m]
  double max_range_m = 30.0;  ///< returns beyond are ruptures [m]
  /// Borges & Aldon's worst incidence angle λ: consecutive points farther apart than
  /// D_max = r_prev * sin(Δφ) / sin(λ - Δφ) + 3 σ are a breakpoint [deg].
  double breakpoint_lambda_deg = 10.0;
  double breakpoint_sigma_m = 0.01;   ///< range noise σ of the sensor [m]
  double split_distance_m = 0.05;     ///< iterative end-point fit splits beyond this [m]
  std::size_t min_segment_points = 4; ///< shorter groups are dropped
  double min_wall_length_m = 0.25;    ///< shorter lines are not walls [m]
  double merge_angle_deg = 5.0;       ///< neighbours this parallel ...
  double merge_gap_m = 0.3;           ///< ... this close (end to start) are merged if one line fits both [m]
  double door_min_width_m = 0.8;      ///< door gap width range [m]
  double door_max_width_m = 1.2;
  double door_max_angle_deg = 10.0;   ///< the walls either side of a door are this parallel [deg]
  double door_max_offset_m = 0.15;    ///< ... and this close to one line [m]
  double door_clearance_m = 0.1;      ///< a point this far in front of the gap closes it [m]
  double corner_min_angle_deg = 30.0; ///< walls meeting at less (or more than 180 minus this) are no corner
  double corner_max_gap_m = 0.3;      ///< wall ends within this of the lines' crossing: a seen corner [m]
  double corner_potential_gap_m = 1.0;  ///< ... within this: a potential corner [m]
  double corridor_min_width_m = 0.8;  ///< facing walls this far apart ... [m]
  double corridor_max_width_m = 4.0;
  double corridor_min_length_m = 2.0; ///< ... seen side by side over this length form a corridor [m]
  double corridor_max_angle_deg = 10.0;  ///< walls of one side, and the two sides, this parallel [deg]
  double corridor_line_offset_m = 0.2;   ///< walls of one side lie this close to one line [m]

  /// @brief Throws std::invalid_argument when a value is out of range.
  void validate() const;
};

/// @brief A line fitted by total least squares: unit normal n and offset c with n . p = c.
struct LineFit
{
  Eigen::Vector2d normal = Eigen::Vector2d::UnitY();
  double offset = 0.0;
  double rms_m = 0.0;
  double max_residual_m = 0.0;
  /// @brief Orthogonal projection of p onto the line.
  Eigen::Vector2d project(const Eigen::Vector2d& p) const { return p - (normal.dot(p) - offset) * normal; }
};

/// @brief Total least-squares line of points[begin, end) (at least two distinct points).
LineFit fitLine(const PointList2D& points, std::size_t begin, std::size_t end);

/// @brief Borges & Aldon's adaptive breakpoint distance D_max [m] for a previous range r_prev [m],
/// a beam spacing dphi [rad], λ [rad] and σ [m].
double breakpointDistance(double r_prev, double dphi_rad, double lambda_rad, double sigma_m);

/**
 * @brief Iterative end-point fit of points[begin, end): split at the point farthest from the chord
 * of the first and last point while it is farther than `threshold_m`. Returns the half-open
 * ranges [first, last) of the pieces, in order; neighbouring pieces share no point.
 */
std::vector<std::pair<std::size_t, std::size_t>> iterativeEndPointFit(const PointList2D& points,
                                                                      std::size_t begin, std::size_t end,
                                                                      double threshold_m);

/**
 * @brief Seed 002's line feature pipeline: rupture points, adaptive breakpoints, continuous
 * segments, iterative end-point fit, merge of collinear neighbours, least-squares walls, then
 * doors, corners and corridors. Stateless and deterministic.
 */
class LineFeatureExtractor
{
public:
  explicit LineFeatureExtractor(const LineFeatureConfig& config = LineFeatureConfig());
  /// @brief Features of `scan` in its own frame; ok false with a reason for an unusable scan.
  ScanFeatures extract(const RangeScan& scan) const;
  const LineFeatureConfig& config() const { return config_; }

private:
  void findDoors(ScanFeatures& f, bool full_circle, double increment_rad) const;
  void findCorners(ScanFeatures& f, bool full_circle, const std::vector<std::uint32_t>& group_of) const;
  void findCorridors(ScanFeatures& f) const;

  LineFeatureConfig config_;
};

/// @brief Moves features by a rigid transform (e.g. from the robot's frame into the map).
void transformFeatures(ScanFeatures& features, const Eigen::Isometry2d& transform);

/// @brief Configuration of alignScans. Distances in metres.
struct ProcrustesConfig
{
  int max_iterations = 40;
  double max_correspondence_m = 1.0;  ///< nearest neighbours farther apart are not paired [m]
  double min_correspondence_m = 0.05; ///< the pairing distance never shrinks below this [m]
  double convergence_m = 1e-4;        ///< stop when an iteration moves the source less [m]
  std::size_t min_pairs = 10;         ///< fewer pairs: no alignment

  /// @brief Throws std::invalid_argument when a value is out of range.
  void validate() const;
};

/// @brief Result of alignScans: `transform` maps source points onto the target.
struct ProcrustesResult
{
  bool ok = false;
  std::string reason;
  Eigen::Isometry2d transform = Eigen::Isometry2d::Identity();
  double rms_m = 0.0;       ///< RMS distance of the final pairs [m]
  std::size_t n_pairs = 0;  ///< pairs in the final iteration
  int iterations = 0;
  /// Share of the source points within 2 * min_correspondence_m of a target point once aligned:
  /// how much of the two scans overlaps, to compare alignments from different starts.
  double inlier_fraction = 0.0;
};

/**
 * @brief Rigid 2D alignment (rotation and translation; no scaling, no reflection) of two scans'
 * points, seed 002 §2.3: pair every source point with its nearest target point, solve the
 * Procrustes problem of the pairs (Eigen::umeyama without scaling), move the source, repeat. The
 * pairing distance adapts to three times the median pair distance between the configured bounds.
 */
ProcrustesResult alignScans(const PointList2D& source, const PointList2D& target, const ProcrustesConfig& config,
                            const Eigen::Isometry2d& initial = Eigen::Isometry2d::Identity());

/// @brief Points of the scan's valid returns (same rules as the extractor's ruptures) [m].
PointList2D scanPoints(const RangeScan& scan, double min_range_m, double max_range_m);

}  // namespace sparse_nav

#endif  // SPARSE_NAV_CORE_LINE_FEATURES_H
