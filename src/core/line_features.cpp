#include "sparse_nav/core/line_features.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <unordered_map>
#include <utility>

namespace sparse_nav
{
namespace
{
constexpr double kDegToRad = M_PI / 180.0;
constexpr double kTwoPi = 2.0 * M_PI;

using Range = std::pair<std::size_t, std::size_t>;

double wrapAngle(double a)
{
  a = std::fmod(a + M_PI, kTwoPi);
  if (a < 0.0)
    a += kTwoPi;
  return a - M_PI;
}

double cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b)
{
  return a.x() * b.y() - a.y() * b.x();
}

/// Total least squares over several index ranges of `points`.
LineFit fitRanges(const PointList2D& points, const std::vector<Range>& ranges)
{
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  std::size_t n = 0;
  for (const auto& r : ranges)
    for (std::size_t i = r.first; i < r.second; ++i, ++n)
      mean += points[i];
  LineFit fit;
  if (n < 2)
    return fit;
  mean /= static_cast<double>(n);
  double sxx = 0.0, sxy = 0.0, syy = 0.0;
  for (const auto& r : ranges)
    for (std::size_t i = r.first; i < r.second; ++i)
    {
      const Eigen::Vector2d d = points[i] - mean;
      sxx += d.x() * d.x();
      sxy += d.x() * d.y();
      syy += d.y() * d.y();
    }
  // The normal is the eigenvector of the smaller eigenvalue of the scatter matrix.
  const double theta = 0.5 * std::atan2(2.0 * sxy, sxx - syy);  // direction of the line
  fit.normal = Eigen::Vector2d(-std::sin(theta), std::cos(theta));
  fit.offset = fit.normal.dot(mean);
  double sum2 = 0.0;
  for (const auto& r : ranges)
    for (std::size_t i = r.first; i < r.second; ++i)
    {
      const double e = std::abs(fit.normal.dot(points[i]) - fit.offset);
      sum2 += e * e;
      fit.max_residual_m = std::max(fit.max_residual_m, e);
    }
  fit.rms_m = std::sqrt(sum2 / static_cast<double>(n));
  return fit;
}

/// A wall from a fit and the ranges it was fitted to; direction follows the point order.
ScanWall makeWall(const PointList2D& points, const LineFit& fit, const std::vector<Range>& ranges)
{
  ScanWall w;
  w.first_index = ranges.front().first;
  w.last_index = ranges.back().second - 1;
  w.start = fit.project(points[w.first_index]);
  w.end = fit.project(points[w.last_index]);
  w.rms_m = fit.rms_m;
  for (const auto& r : ranges)
    w.n_points += r.second - r.first;
  return w;
}

void iepf(const PointList2D& points, std::size_t begin, std::size_t end, double threshold,
          std::vector<Range>& out)
{
  if (end - begin < 3)
  {
    out.emplace_back(begin, end);
    return;
  }
  const Eigen::Vector2d a = points[begin];
  const Eigen::Vector2d chord = points[end - 1] - a;
  const double len = chord.norm();
  std::size_t split = begin;
  double worst = -1.0;
  for (std::size_t i = begin + 1; i + 1 < end; ++i)
  {
    const double d = len > 1e-12 ? std::abs(cross(chord, points[i] - a)) / len : (points[i] - a).norm();
    if (d > worst)
    {
      worst = d;
      split = i;
    }
  }
  if (worst <= threshold)
  {
    out.emplace_back(begin, end);
    return;
  }
  // The split point starts the second piece.
  iepf(points, begin, split, threshold, out);
  iepf(points, split, end, threshold, out);
}

/// Crossing of the lines through a (direction da) and b (direction db); false when parallel.
bool intersect(const Eigen::Vector2d& a, const Eigen::Vector2d& da, const Eigen::Vector2d& b,
               const Eigen::Vector2d& db, Eigen::Vector2d& x)
{
  const double den = cross(da, db);
  if (std::abs(den) < 1e-9)
    return false;
  x = a + da * (cross(b - a, db) / den);
  return true;
}

/// Distance along the ray from the origin through p to the segment a-b, or -1 when it misses.
double rayToSegment(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b)
{
  const double r = p.norm();
  if (r < 1e-12)
    return -1.0;
  const Eigen::Vector2d d = p / r;
  const Eigen::Vector2d e = b - a;
  const double den = cross(d, e);
  if (std::abs(den) < 1e-12)
    return -1.0;
  const double t = cross(a, e) / den;  // along the ray
  const double u = cross(a, d) / den;  // along the segment
  if (t <= 0.0 || u < 0.0 || u > 1.0)
    return -1.0;
  return t;
}

void requireRange(bool ok, const std::string& what)
{
  if (!ok)
    throw std::invalid_argument(what);
}
}  // namespace

std::string RangeScan::check() const
{
  if (ranges.empty())
    return "scan has no beams";
  if (!std::isfinite(angle_min_rad) || !std::isfinite(angle_max_rad) || !std::isfinite(angle_increment_rad))
    return "scan angle fields are not finite";
  if (!(angle_increment_rad > 0.0))
    return "scan angle_increment must be > 0 (got " + std::to_string(angle_increment_rad) + ")";
  const double expected = angle_min_rad + static_cast<double>(ranges.size() - 1) * angle_increment_rad;
  // One increment of slack: drivers disagree on whether angle_max is the last beam or one past it.
  if (std::abs(angle_max_rad - expected) > angle_increment_rad + 1e-6)
    return "scan angle fields do not match the number of ranges: angle_min + (n - 1) * increment = " +
           std::to_string(expected) + " rad but angle_max = " + std::to_string(angle_max_rad) + " rad (n = " +
           std::to_string(ranges.size()) + ")";
  if (static_cast<double>(ranges.size() - 1) * angle_increment_rad > kTwoPi + 1e-6)
    return "scan covers more than a full turn";
  if (std::isnan(range_min_m) || std::isnan(range_max_m) || range_min_m < 0.0 || !(range_max_m > range_min_m))
    return "scan range_min/range_max are invalid";
  return std::string();
}

bool RangeScan::fullCircle() const
{
  return static_cast<double>(ranges.size()) * angle_increment_rad >= kTwoPi - 0.5 * angle_increment_rad;
}

void VirtualScanConfig::validate() const
{
  requireRange(n_beams >= 8 && n_beams <= 100000, "virtual scan n_beams must be in [8, 100000]");
  requireRange(std::isfinite(min_height_m) && std::isfinite(max_height_m) && max_height_m > min_height_m,
               "virtual scan max_height_m must be > min_height_m");
  requireRange(range_min_m >= 0.0 && std::isfinite(range_max_m) && range_max_m > range_min_m,
               "virtual scan range_max_m must be finite and > range_min_m >= 0");
}

RangeScan virtualScan(const PointList& points, const Pose2D& pose, const VirtualScanConfig& config)
{
  config.validate();
  RangeScan scan;
  const double inc = kTwoPi / config.n_beams;
  scan.angle_min_rad = -M_PI;
  scan.angle_increment_rad = inc;
  scan.angle_max_rad = -M_PI + (config.n_beams - 1) * inc;
  scan.range_min_m = config.range_min_m;
  scan.range_max_m = config.range_max_m;
  scan.ranges.assign(static_cast<std::size_t>(config.n_beams), std::numeric_limits<float>::infinity());
  if (!std::isfinite(pose.x_m) || !std::isfinite(pose.y_m) || !std::isfinite(pose.yaw_rad))
    return scan;
  for (const auto& p : points)
  {
    if (!p.allFinite() || p.z() < config.min_height_m || p.z() > config.max_height_m)
      continue;
    const double dx = p.x() - pose.x_m, dy = p.y() - pose.y_m;
    const double r = std::hypot(dx, dy);
    if (r < config.range_min_m || r > config.range_max_m)
      continue;
    const double bearing = wrapAngle(std::atan2(dy, dx) - pose.yaw_rad);
    long bin = std::lround((bearing + M_PI) / inc);
    if (bin >= config.n_beams)
      bin -= config.n_beams;
    float& slot = scan.ranges[static_cast<std::size_t>(bin)];
    slot = std::min(slot, static_cast<float>(r));
  }
  return scan;
}

const char* cornerTypeName(CornerType type)
{
  switch (type)
  {
    case CornerType::kInner:
      return "inner";
    case CornerType::kOuter:
      return "outer";
    default:
      return "potential";
  }
}

CornerDistances cornerDistances(const Eigen::Vector2d& robot, const Eigen::Vector2d& corner, const Eigen::Vector2d& a,
                                const Eigen::Vector2d& b)
{
  CornerDistances d;
  d.robot_corner_m = (robot - corner).norm();
  const Eigen::Vector2d leg = b - a;
  const double len = leg.norm();
  if (len < 1e-12)
  {
    d.robot_leg_m = (robot - a).norm();
    d.corner_leg_m = (corner - a).norm();
    return d;
  }
  d.robot_leg_m = std::abs(cross(leg, robot - a)) / len;
  d.corner_leg_m = std::abs(cross(leg, corner - a)) / len;
  return d;
}

CornerType classifyCorner(const CornerDistances& d)
{
  const bool rc_lt_rl = d.robot_corner_m < d.robot_leg_m;
  const bool rl_lt_cl = d.robot_leg_m < d.corner_leg_m;
  return rc_lt_rl && !rl_lt_cl ? CornerType::kInner : CornerType::kOuter;
}

void LineFeatureConfig::validate() const
{
  requireRange(min_range_m >= 0.0 && max_range_m > min_range_m, "max_range_m must be > min_range_m >= 0");
  requireRange(breakpoint_lambda_deg > 0.0 && breakpoint_lambda_deg < 90.0, "breakpoint_lambda_deg must be in (0, 90)");
  requireRange(breakpoint_sigma_m >= 0.0, "breakpoint_sigma_m must be >= 0");
  requireRange(split_distance_m > 0.0, "split_distance_m must be > 0");
  requireRange(min_segment_points >= 2, "min_segment_points must be >= 2");
  requireRange(min_wall_length_m >= 0.0, "min_wall_length_m must be >= 0");
  requireRange(merge_angle_deg >= 0.0 && merge_angle_deg < 90.0, "merge_angle_deg must be in [0, 90)");
  requireRange(merge_gap_m >= 0.0, "merge_gap_m must be >= 0");
  requireRange(door_min_width_m > 0.0 && door_max_width_m >= door_min_width_m,
               "door widths must satisfy 0 < door_min_width_m <= door_max_width_m");
  requireRange(door_max_angle_deg >= 0.0 && door_max_angle_deg < 90.0, "door_max_angle_deg must be in [0, 90)");
  requireRange(door_max_offset_m >= 0.0 && door_clearance_m >= 0.0, "door offsets must be >= 0");
  requireRange(corner_min_angle_deg > 0.0 && corner_min_angle_deg < 90.0, "corner_min_angle_deg must be in (0, 90)");
  requireRange(corner_max_gap_m >= 0.0 && corner_potential_gap_m >= corner_max_gap_m,
               "corner gaps must satisfy 0 <= corner_max_gap_m <= corner_potential_gap_m");
  requireRange(corridor_min_width_m > 0.0 && corridor_max_width_m >= corridor_min_width_m,
               "corridor widths must satisfy 0 < corridor_min_width_m <= corridor_max_width_m");
  requireRange(corridor_min_length_m >= 0.0 && corridor_line_offset_m >= 0.0, "corridor lengths must be >= 0");
  requireRange(corridor_max_angle_deg >= 0.0 && corridor_max_angle_deg < 90.0,
               "corridor_max_angle_deg must be in [0, 90)");
}

LineFit fitLine(const PointList2D& points, std::size_t begin, std::size_t end)
{
  return fitRanges(points, { Range(begin, end) });
}

double breakpointDistance(double r_prev, double dphi_rad, double lambda_rad, double sigma_m)
{
  return r_prev * std::sin(dphi_rad) / std::sin(lambda_rad - dphi_rad) + 3.0 * sigma_m;
}

std::vector<Range> iterativeEndPointFit(const PointList2D& points, std::size_t begin, std::size_t end,
                                        double threshold_m)
{
  std::vector<Range> out;
  if (end > begin && end <= points.size())
    iepf(points, begin, end, threshold_m, out);
  return out;
}

PointList2D scanPoints(const RangeScan& scan, double min_range_m, double max_range_m)
{
  PointList2D out;
  if (!scan.check().empty())
    return out;
  out.reserve(scan.ranges.size());
  const double lo = std::max(min_range_m, scan.range_min_m);
  const double hi = std::min(max_range_m, scan.range_max_m);
  for (std::size_t i = 0; i < scan.ranges.size(); ++i)
  {
    const double r = scan.ranges[i];
    if (!std::isfinite(r) || r <= lo || r > hi)
      continue;
    const double a = scan.angle_min_rad + static_cast<double>(i) * scan.angle_increment_rad;
    out.emplace_back(r * std::cos(a), r * std::sin(a));
  }
  return out;
}

LineFeatureExtractor::LineFeatureExtractor(const LineFeatureConfig& config) : config_(config)
{
  config_.validate();
}

ScanFeatures LineFeatureExtractor::extract(const RangeScan& scan) const
{
  ScanFeatures f;
  f.reason = scan.check();
  if (!f.reason.empty())
    return f;
  const std::size_t n = scan.ranges.size();
  const double lo = std::max(config_.min_range_m, scan.range_min_m);
  const double hi = std::min(config_.max_range_m, scan.range_max_m);
  const double inc = scan.angle_increment_rad;
  const double lambda = config_.breakpoint_lambda_deg * kDegToRad;
  // Borges & Aldon's bound only makes sense while the beam spacing is below λ.
  const double dmax_factor = inc < lambda ? std::sin(inc) / std::sin(lambda - inc) : 1e9;
  const double dmax_noise = 3.0 * config_.breakpoint_sigma_m;

  std::vector<std::uint8_t> valid(n);
  std::size_t n_valid = 0;
  for (std::size_t i = 0; i < n; ++i)
  {
    const float r = scan.ranges[i];
    valid[i] = std::isfinite(r) && r > lo && r <= hi;
    n_valid += valid[i];
  }
  f.n_ruptures = n - n_valid;
  if (n_valid == 0)
  {
    f.reason = "no valid return: every range is NaN, Inf, 0 or beyond the range limits";
    return f;
  }
  if (n_valid < config_.min_segment_points)
  {
    f.reason = "only " + std::to_string(n_valid) + " valid return(s); a wall needs " +
               std::to_string(config_.min_segment_points);
    return f;
  }
  auto pointOf = [&](std::size_t i) {
    const double a = scan.angle_min_rad + static_cast<double>(i) * inc;
    const double r = scan.ranges[i];
    return Eigen::Vector2d(r * std::cos(a), r * std::sin(a));
  };
  auto isBreak = [&](std::size_t prev, std::size_t cur, const Eigen::Vector2d& p_prev, const Eigen::Vector2d& p_cur) {
    if (!valid[prev] || !valid[cur])
      return true;
    return (p_cur - p_prev).norm() > scan.ranges[prev] * dmax_factor + dmax_noise;
  };

  // A full turn has no natural first beam: start right after a break so no wall straddles the seam.
  const bool full = scan.fullCircle();
  std::size_t start = 0;
  bool seamless = full;
  if (full)
  {
    for (std::size_t j = 0; j < n; ++j)
    {
      const std::size_t prev = (j + n - 1) % n;
      if (!valid[prev] || !valid[j] || isBreak(prev, j, pointOf(prev), pointOf(j)))
      {
        start = j;
        seamless = false;
        break;
      }
    }
  }

  f.points.reserve(n_valid);
  std::vector<Range> groups;
  std::size_t prev_beam = n;  // none yet
  Eigen::Vector2d prev_point = Eigen::Vector2d::Zero();
  std::size_t group_begin = 0;
  for (std::size_t m = 0; m < n; ++m)
  {
    const std::size_t beam = (start + m) % n;
    if (!valid[beam])
    {
      prev_beam = n;
      continue;
    }
    const Eigen::Vector2d p = pointOf(beam);
    bool new_group = prev_beam == n;
    if (!new_group && isBreak(prev_beam, beam, prev_point, p))
    {
      new_group = true;
      ++f.n_breakpoints;
    }
    if (new_group && f.points.size() > group_begin)
    {
      groups.emplace_back(group_begin, f.points.size());
      group_begin = f.points.size();
    }
    f.points.push_back(p);
    prev_beam = beam;
    prev_point = p;
  }
  if (f.points.size() > group_begin)
    groups.emplace_back(group_begin, f.points.size());

  // Continuous segments split at corners, then collinear neighbours merged again.
  std::vector<Range> pieces;
  for (const auto& g : groups)
  {
    if (g.second - g.first < config_.min_segment_points)
      continue;
    iepf(f.points, g.first, g.second, config_.split_distance_m, pieces);
  }
  std::vector<std::vector<Range>> segments;
  std::vector<LineFit> fits;
  const double merge_cos = std::cos(config_.merge_angle_deg * kDegToRad);
  // Appends b's ranges to a's when the two are close, parallel, and one line fits both.
  auto tryMerge = [&](std::vector<Range>& a_ranges, LineFit& a_fit, const std::vector<Range>& b_ranges,
                      const LineFit& b_fit) {
    const ScanWall a = makeWall(f.points, a_fit, a_ranges);
    const ScanWall b = makeWall(f.points, b_fit, b_ranges);
    if ((b.start - a.end).norm() > config_.merge_gap_m || a.direction().dot(b.direction()) < merge_cos)
      return false;
    std::vector<Range> joined = a_ranges;
    joined.insert(joined.end(), b_ranges.begin(), b_ranges.end());
    const LineFit both = fitRanges(f.points, joined);
    if (both.max_residual_m > config_.split_distance_m)
      return false;
    a_ranges = joined;
    a_fit = both;
    return true;
  };
  for (const auto& piece : pieces)
  {
    if (piece.second - piece.first < config_.min_segment_points)
      continue;
    ++f.n_segments;
    std::vector<Range> seg{ piece };
    const LineFit fit = fitRanges(f.points, seg);
    // Too short to be a wall (a pillar, a chair leg): it must not stop the wall behind it merging.
    if (makeWall(f.points, fit, seg).length() < config_.min_wall_length_m)
      continue;
    if (!segments.empty() && tryMerge(segments.back(), fits.back(), seg, fit))
      continue;
    segments.push_back(seg);
    fits.push_back(fit);
  }
  // A full turn without any break starts at an arbitrary beam: the wall there is cut in two.
  if (seamless && segments.size() >= 2 && tryMerge(segments.back(), fits.back(), segments.front(), fits.front()))
  {
    segments.erase(segments.begin());
    fits.erase(fits.begin());
  }
  for (std::size_t s = 0; s < segments.size(); ++s)
  {
    ScanWall w = makeWall(f.points, fits[s], segments[s]);
    if (w.length() >= config_.min_wall_length_m && w.length() > 0.0)
      f.walls.push_back(w);
  }
  findDoors(f, full, inc);
  std::vector<std::uint32_t> group_of(f.points.size(), 0);
  for (std::size_t g = 0; g < groups.size(); ++g)
    for (std::size_t k = groups[g].first; k < groups[g].second; ++k)
      group_of[k] = static_cast<std::uint32_t>(g);
  findCorners(f, full, group_of);
  findCorridors(f);
  f.ok = true;
  return f;
}

void LineFeatureExtractor::findDoors(ScanFeatures& f, bool full_circle, double increment_rad) const
{
  const std::size_t nw = f.walls.size();
  const std::size_t np = f.points.size();
  const double cos_max = std::cos(config_.door_max_angle_deg * kDegToRad);
  const double sin_max = std::sin(config_.door_max_angle_deg * kDegToRad);
  // A wall's last return falls short of its true end by up to one beam: the end lies between that
  // return and where the next beam crosses the wall's line. The midpoint is the jamb; the two
  // bounds give the door's narrowest and widest possible width.
  struct Jamb
  {
    Eigen::Vector2d seen, beyond, mid;
  };
  auto jamb = [](const ScanWall& w, const Eigen::Vector2d& last, double dphi) {
    const double ang = std::atan2(last.y(), last.x()) + dphi;
    const Eigen::Vector2d ray(std::cos(ang), std::sin(ang));
    Eigen::Vector2d x;
    if (!intersect(Eigen::Vector2d::Zero(), ray, w.start, w.direction(), x) || x.dot(ray) <= 0.0 ||
        (x - last).norm() > 0.5)
      x = last;
    return Jamb{ last, x, 0.5 * (last + x) };
  };
  std::vector<std::uint8_t> used_after(nw, 0);
  for (std::size_t i = 0; i < nw; ++i)
  {
    const ScanWall& a = f.walls[i];
    const Eigen::Vector2d da = a.direction();
    const Eigen::Vector2d na(-da.y(), da.x());
    const Jamb jamb_a = jamb(a, a.end, increment_rad);
    const Eigen::Vector2d ja = jamb_a.mid;
    // Walls after wall i in scan order (past the seam of a full turn too); the gap's far side may
    // show other walls in between.
    const std::size_t max_k = full_circle ? nw - 1 : nw - 1 - i;
    for (std::size_t k = 1; k <= max_k; ++k)
    {
      const std::size_t j = (i + k) % nw;
      const ScanWall& b = f.walls[j];
      if (used_after[j])
        continue;
      const Jamb jamb_b = jamb(b, b.start, -increment_rad);
      const Eigen::Vector2d jb = jamb_b.mid;
      const Eigen::Vector2d gap = jb - ja;
      const double width = gap.norm();
      const double widest = (jamb_b.seen - jamb_a.seen).norm();
      const double narrowest = (jamb_b.beyond - jamb_a.beyond).norm();
      if (std::max(widest, width) < config_.door_min_width_m || std::min(narrowest, width) > config_.door_max_width_m)
        continue;
      const Eigen::Vector2d db = b.direction();
      const Eigen::Vector2d nb(-db.y(), db.x());
      // A gap in one wall line, or the far end of a recess whose two side walls face each other.
      const bool in_line = da.dot(db) >= cos_max && gap.dot(da) >= 0.5 * width &&
                           std::abs(na.dot(b.start - a.start)) <= config_.door_max_offset_m &&
                           std::abs(nb.dot(a.end - b.start)) <= config_.door_max_offset_m;
      const bool recess = da.dot(db) <= -cos_max && std::abs(gap.dot(da)) <= sin_max * width &&
                          std::abs(gap.dot(db)) <= sin_max * width;
      if (!in_line && !recess)
        continue;
      bool open = true;
      for (std::size_t q = (a.last_index + 1) % np; q != b.first_index && open; q = (q + 1) % np)
      {
        const double t = rayToSegment(f.points[q], ja, jb);
        open = t < 0.0 || f.points[q].norm() >= t - config_.door_clearance_m;
      }
      if (!open)
        continue;
      ScanDoor door;
      door.start = ja;
      door.end = jb;
      door.wall_before = i;
      door.wall_after = j;
      f.doors.push_back(door);
      used_after[j] = 1;
      break;
    }
  }
}

void LineFeatureExtractor::findCorners(ScanFeatures& f, bool full_circle,
                                       const std::vector<std::uint32_t>& group_of) const
{
  const std::size_t nw = f.walls.size();
  if (nw < 2)
    return;
  const double min_angle = config_.corner_min_angle_deg;
  const std::size_t pairs = full_circle ? nw : nw - 1;
  for (std::size_t i = 0; i < pairs; ++i)
  {
    const std::size_t j = (i + 1) % nw;
    const ScanWall& a = f.walls[i];
    const ScanWall& b = f.walls[j];
    const Eigen::Vector2d da = a.direction(), db = b.direction();
    Eigen::Vector2d x;
    if (!intersect(a.start, da, b.start, db, x))
      continue;
    // Angle between the legs at the corner: from the corner back along wall a and on along wall b.
    const double angle = std::acos(std::max(-1.0, std::min(1.0, -da.dot(db)))) / kDegToRad;
    if (angle < min_angle || angle > 180.0 - min_angle)
      continue;
    const double gap = std::max((a.end - x).norm(), (b.start - x).norm());
    if (gap > config_.corner_potential_gap_m)
      continue;
    // The crossing must lie past (or near) the end of a and before (or near) the start of b.
    if ((x - a.start).dot(da) < a.length() - config_.corner_max_gap_m ||
        (x - b.start).dot(db) > config_.corner_max_gap_m)
      continue;
    ScanCorner c;
    c.point = x;
    c.wall_in = i;
    c.wall_out = j;
    c.angle_deg = angle;
    // The missing leg joins the points at the robot-corner distance along both walls: with legs
    // that long the seed's comparison is exact for every corner the robot can see (far wall ends
    // would flip a corner seen at a grazing angle).
    const double leg = x.norm();
    c.distances = cornerDistances(Eigen::Vector2d::Zero(), x, x - da * leg, x + db * leg);
    // Seen only when the scan runs on from one wall to the other without a break: across a
    // breakpoint one wall may pass behind the other (an occlusion edge, not a corner).
    const bool continuous = group_of[a.last_index] == group_of[b.first_index];
    c.type = gap <= config_.corner_max_gap_m && continuous ? classifyCorner(c.distances) : CornerType::kPotential;
    f.corners.push_back(c);
    // Seed 002: the two walls of a corner share its point.
    if (c.type != CornerType::kPotential)
    {
      f.walls[i].end = x;
      f.walls[j].start = x;
    }
  }
}

void LineFeatureExtractor::findCorridors(ScanFeatures& f) const
{
  struct Line
  {
    std::vector<std::size_t> walls;
    Eigen::Vector2d dir, normal;
    double offset;
    double lo, hi;  // extent along dir
  };
  const std::size_t nw = f.walls.size();
  if (nw < 2)
    return;
  const double cos_max = std::cos(config_.corridor_max_angle_deg * kDegToRad);
  std::vector<std::size_t> order(nw);
  for (std::size_t i = 0; i < nw; ++i)
    order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return f.walls[a].length() > f.walls[b].length(); });
  std::vector<Line> lines;
  std::vector<std::uint8_t> assigned(nw, 0);
  for (std::size_t oi = 0; oi < nw; ++oi)
  {
    const std::size_t s = order[oi];
    if (assigned[s])
      continue;
    Line line;
    line.dir = f.walls[s].direction();
    line.normal = Eigen::Vector2d(-line.dir.y(), line.dir.x());
    line.offset = line.normal.dot(f.walls[s].start);
    line.lo = std::numeric_limits<double>::infinity();
    line.hi = -line.lo;
    for (std::size_t oj = oi; oj < nw; ++oj)
    {
      const std::size_t k = order[oj];
      const ScanWall& w = f.walls[k];
      if (assigned[k] || w.direction().dot(line.dir) < cos_max ||
          std::abs(line.normal.dot(0.5 * (w.start + w.end)) - line.offset) > config_.corridor_line_offset_m)
        continue;
      assigned[k] = 1;
      line.walls.push_back(k);
      for (const auto& p : { w.start, w.end })
      {
        line.lo = std::min(line.lo, line.dir.dot(p));
        line.hi = std::max(line.hi, line.dir.dot(p));
      }
    }
    std::sort(line.walls.begin(), line.walls.end());
    lines.push_back(line);
  }
  struct Pair
  {
    double width, lo, hi;
    std::size_t a, b;
  };
  std::vector<Pair> candidates;
  for (std::size_t a = 0; a < lines.size(); ++a)
    for (std::size_t b = a + 1; b < lines.size(); ++b)
    {
      const Line& la = lines[a];
      const Line& lb = lines[b];
      if (la.dir.dot(lb.dir) > -cos_max)
        continue;
      // Facing: each line lies on the other's seen (left) side.
      const Eigen::Vector2d mid_a = la.dir * (0.5 * (la.lo + la.hi)) + la.normal * la.offset;
      const Eigen::Vector2d mid_b = lb.dir * (0.5 * (lb.lo + lb.hi)) + lb.normal * lb.offset;
      const double wa = la.normal.dot(mid_b) - la.offset;
      const double wb = lb.normal.dot(mid_a) - lb.offset;
      if (wa <= 0.0 || wb <= 0.0)
        continue;
      const double width = 0.5 * (wa + wb);
      if (width < config_.corridor_min_width_m || width > config_.corridor_max_width_m)
        continue;
      // lb's extent along la.dir is reversed because the two directions are opposite.
      const double lo = std::max(la.lo, -lb.hi), hi = std::min(la.hi, -lb.lo);
      if (hi - lo < config_.corridor_min_length_m)
        continue;
      candidates.push_back({ width, lo, hi, a, b });
    }
  std::sort(candidates.begin(), candidates.end(), [](const Pair& x, const Pair& y) { return x.width < y.width; });
  std::vector<std::uint8_t> used(lines.size(), 0);
  for (const auto& c : candidates)
  {
    if (used[c.a] || used[c.b])
      continue;
    used[c.a] = used[c.b] = 1;
    const Line& la = lines[c.a];
    ScanCorridor corridor;
    corridor.side_a = la.walls;
    corridor.side_b = lines[c.b].walls;
    corridor.width_m = c.width;
    corridor.length_m = c.hi - c.lo;
    const Eigen::Vector2d centre = la.normal * (la.offset + 0.5 * c.width);
    corridor.axis_start = centre + la.dir * c.lo;
    corridor.axis_end = centre + la.dir * c.hi;
    f.corridors.push_back(corridor);
  }
}

void transformFeatures(ScanFeatures& features, const Eigen::Isometry2d& t)
{
  for (auto& w : features.walls)
  {
    w.start = t * w.start;
    w.end = t * w.end;
  }
  for (auto& d : features.doors)
  {
    d.start = t * d.start;
    d.end = t * d.end;
  }
  for (auto& c : features.corners)
    c.point = t * c.point;
  for (auto& c : features.corridors)
  {
    c.axis_start = t * c.axis_start;
    c.axis_end = t * c.axis_end;
  }
  for (auto& p : features.points)
    p = t * p;
}

void ProcrustesConfig::validate() const
{
  requireRange(max_iterations >= 1, "max_iterations must be >= 1");
  requireRange(min_correspondence_m > 0.0 && max_correspondence_m >= min_correspondence_m,
               "correspondence distances must satisfy 0 < min_correspondence_m <= max_correspondence_m");
  requireRange(convergence_m >= 0.0, "convergence_m must be >= 0");
  requireRange(min_pairs >= 3, "min_pairs must be >= 3");
}

namespace
{
/// Uniform 2D grid of the target points for nearest-neighbour queries within one cell.
class Grid2
{
public:
  Grid2(const PointList2D& pts, double cell) : pts_(pts), inv_(1.0 / cell)
  {
    for (std::size_t i = 0; i < pts.size(); ++i)
      cells_[key(pts[i])].push_back(static_cast<std::uint32_t>(i));
  }
  /// Nearest point within max_dist of p, or -1.
  long nearest(const Eigen::Vector2d& p, double max_dist, double& dist) const
  {
    const std::int64_t cx = static_cast<std::int64_t>(std::floor(p.x() * inv_));
    const std::int64_t cy = static_cast<std::int64_t>(std::floor(p.y() * inv_));
    long best = -1;
    double best2 = max_dist * max_dist;
    for (std::int64_t dy = -1; dy <= 1; ++dy)
      for (std::int64_t dx = -1; dx <= 1; ++dx)
      {
        auto it = cells_.find(pack(cx + dx, cy + dy));
        if (it == cells_.end())
          continue;
        for (std::uint32_t k : it->second)
        {
          const double d2 = (pts_[k] - p).squaredNorm();
          if (d2 <= best2)
          {
            best2 = d2;
            best = k;
          }
        }
      }
    dist = std::sqrt(best2);
    return best;
  }

private:
  static std::uint64_t pack(std::int64_t x, std::int64_t y)
  {
    return (static_cast<std::uint64_t>(x) << 32) ^ (static_cast<std::uint64_t>(y) & 0xffffffffULL);
  }
  std::uint64_t key(const Eigen::Vector2d& p) const
  {
    return pack(static_cast<std::int64_t>(std::floor(p.x() * inv_)), static_cast<std::int64_t>(std::floor(p.y() * inv_)));
  }
  const PointList2D& pts_;
  double inv_;
  std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> cells_;
};

PointList2D finitePoints(const PointList2D& in)
{
  PointList2D out;
  out.reserve(in.size());
  for (const auto& p : in)
    if (p.allFinite() && p.cwiseAbs().maxCoeff() < 1e6)
      out.push_back(p);
  return out;
}
}  // namespace

ProcrustesResult alignScans(const PointList2D& source_in, const PointList2D& target_in, const ProcrustesConfig& config,
                            const Eigen::Isometry2d& initial)
{
  config.validate();
  ProcrustesResult res;
  const PointList2D source = finitePoints(source_in);
  const PointList2D target = finitePoints(target_in);
  if (source.size() < config.min_pairs || target.size() < config.min_pairs)
  {
    res.reason = "too few finite points to align (source " + std::to_string(source.size()) + ", target " +
                 std::to_string(target.size()) + ", need " + std::to_string(config.min_pairs) + ")";
    return res;
  }
  if (!initial.matrix().allFinite())
  {
    res.reason = "initial transform is not finite";
    return res;
  }
  const Grid2 grid(target, config.max_correspondence_m);
  Eigen::Isometry2d t = initial;
  double threshold = config.max_correspondence_m;
  Eigen::Matrix2Xd src(2, source.size()), dst(2, source.size());
  std::vector<double> dists;
  dists.reserve(source.size());
  for (int it = 0; it < config.max_iterations; ++it)
  {
    std::size_t k = 0;
    dists.clear();
    double sum2 = 0.0;
    for (const auto& p : source)
    {
      double d = 0.0;
      const long q = grid.nearest(t * p, threshold, d);
      if (q < 0)
        continue;
      src.col(k) = p;
      dst.col(k) = target[static_cast<std::size_t>(q)];
      dists.push_back(d);
      sum2 += d * d;
      ++k;
    }
    res.iterations = it + 1;
    if (k < config.min_pairs)
    {
      res.reason = "only " + std::to_string(k) + " point pairs within " + std::to_string(threshold) + " m";
      res.transform = t;
      return res;
    }
    res.n_pairs = k;
    res.rms_m = std::sqrt(sum2 / static_cast<double>(k));
    const Eigen::Matrix3d m = Eigen::umeyama(src.leftCols(k), dst.leftCols(k), false);
    Eigen::Isometry2d next = Eigen::Isometry2d::Identity();
    next.linear() = m.topLeftCorner<2, 2>();
    next.translation() = m.topRightCorner<2, 1>();
    double moved = 0.0;
    for (std::size_t i = 0; i < k; ++i)
      moved = std::max(moved, (next * src.col(i) - t * src.col(i)).norm());
    t = next;
    std::nth_element(dists.begin(), dists.begin() + dists.size() / 2, dists.end());
    threshold = std::min(config.max_correspondence_m,
                         std::max(config.min_correspondence_m, 3.0 * dists[dists.size() / 2]));
    if (moved < config.convergence_m)
      break;
  }
  res.ok = true;
  res.transform = t;
  std::size_t inliers = 0;
  for (const auto& p : source)
  {
    double d = 0.0;
    inliers += grid.nearest(t * p, 2.0 * config.min_correspondence_m, d) >= 0;
  }
  res.inlier_fraction = static_cast<double>(inliers) / static_cast<double>(source.size());
  return res;
}

}  // namespace sparse_nav
