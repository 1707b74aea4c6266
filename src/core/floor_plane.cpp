#include "sparse_nav/core/floor_plane.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/ransac.h>
#include <pcl/sample_consensus/sac_model_perpendicular_plane.h>

#include "kth_smallest.h"
#include "spatial_hash.h"


namespace sparse_nav
{
namespace
{
constexpr double kDegToRad = M_PI / 180.0;
constexpr double kRefitToleranceDeg = 0.5;
constexpr double kWideConeDeg = 45.0;
// A lower envelope outside the cone must hold this many times the points of the best inside it to
// be called a tilted floor (corners of walls make modest envelopes at any tilt).
constexpr double kTiltedSupportRatio = 1.5;
constexpr std::size_t kSearchPoints = 4000;  // points scored per normal in the coarse search
constexpr std::size_t kTiltCheckPoints = 1500;  // points of the sample consensus check of an envelope floor
// ... whose plane beyond the limit must hold this many times the envelope floor's points (on small
// samples the two counts of one tilted floor seen from two normals come out close).
constexpr double kTiltCheckSupportRatio = 1.2;

double tiltDeg(const Eigen::Vector3d& normal, const Eigen::Vector3d& up)
{
  const double c = std::min(1.0, std::abs(normal.normalized().dot(up.normalized())));
  return std::acos(c) / kDegToRad;
}

/// A candidate floor: normal, the height of its slab's lower side, and the points in the slab.
struct Envelope
{
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double low = 0.0;
  std::size_t count = 0;
  double tilt_deg = 0.0;
};

/// Points in [q, q + width] along n, q the low quantile of the heights.
Envelope lowerEnvelope(const std::vector<Eigen::Vector3d>& pts, const Eigen::Vector3d& n, double width,
                       double quantile, std::vector<double>& heights)
{
  Envelope e;
  e.normal = n;
  heights.resize(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i)
  {
    heights[i] = n.dot(pts[i]);
  }
  const std::size_t k = std::min(pts.size() - 1, static_cast<std::size_t>(quantile * static_cast<double>(pts.size())));
  e.low = kthSmallest(heights, k);
  for (double h : heights)
  {
    e.count += (h >= e.low && h <= e.low + width) ? 1 : 0;
  }
  return e;
}

/// Normals within max_deg of up on a square grid of step_deg in the tangent plane of `centre`.
std::vector<Eigen::Vector3d> normalGrid(const Eigen::Vector3d& up, const Eigen::Vector3d& centre, double half_deg,
                                        double step_deg, double max_deg)
{
  const Eigen::Vector3d c = centre.normalized();
  const Eigen::Vector3d e1 = c.unitOrthogonal(), e2 = c.cross(e1);
  const int n = static_cast<int>(std::ceil(half_deg / step_deg));
  std::vector<Eigen::Vector3d> out;
  for (int i = -n; i <= n; ++i)
  {
    for (int j = -n; j <= n; ++j)
    {
      const double a = std::tan(i * step_deg * kDegToRad), b = std::tan(j * step_deg * kDegToRad);
      const Eigen::Vector3d v = (c + a * e1 + b * e2).normalized();
      if (tiltDeg(v, up) <= max_deg + 1e-9 && v.dot(up) > 0.0)
      {
        out.push_back(v);
      }
    }
  }
  return out;
}

/// The best lower envelope among normals within max_deg of up: a coarse grid, then finer ones
/// around the best, down to step_deg.
Envelope searchEnvelope(const std::vector<Eigen::Vector3d>& coarse_pts, const std::vector<Eigen::Vector3d>& fine_pts,
                        const Eigen::Vector3d& up, double max_deg, double step_deg, double width, double quantile)
{
  std::vector<double> heights;
  Envelope best;
  double step = std::max(step_deg, std::min(3.0, max_deg / 4.0));
  for (const auto& n : normalGrid(up, up, max_deg, step, max_deg))
  {
    const Envelope e = lowerEnvelope(coarse_pts, n, width, quantile, heights);
    if (e.count > best.count)
    {
      best = e;
    }
  }
  bool refined = false;
  while (step > step_deg + 1e-9)
  {
    refined = true;
    const double next = std::max(step_deg, step / 3.0);
    const Eigen::Vector3d centre = best.normal;
    best.count = 0;
    for (const auto& n : normalGrid(up, centre, step, next, max_deg))
    {
      const Envelope e = lowerEnvelope(fine_pts, n, width, quantile, heights);
      if (e.count > best.count)
      {
        best = e;
      }
    }
    step = next;
  }
  if (!refined)
  {
    // Scores on the fine points, as the refined ones are.
    best = lowerEnvelope(fine_pts, best.normal, width, quantile, heights);
  }
  best.tilt_deg = tiltDeg(best.normal, up);
  return best;
}

/**
 * The up direction from the walls: local surface normals (PCA over neighbours within radius_m) of
 * planar patches within 45 deg of vertical are perpendicular to up, so up is the direction most
 * perpendicular to them (the smallest eigenvector of the sum of their outer products), refined
 * once with patches within 30 deg of vertical around it. Returns false when too few wall patches
 * agree (no walls, or a cloud without structure).
 */
bool upFromWalls(const std::vector<Eigen::Vector3d>& pts, const Eigen::Vector3d& up0, double radius_m,
                 Eigen::Vector3d& up, std::size_t& n_walls)
{
  PointList cloud;
  cloud.reserve(pts.size());
  for (const auto& p : pts)
  {
    cloud.push_back(p.cast<float>());
  }
  const SpatialHash3 hash(radius_m, cloud);
  const float r2 = static_cast<float>(radius_m * radius_m);
  const std::size_t stride = std::max<std::size_t>(1, pts.size() / 3000);
  std::vector<Eigen::Vector3d> normals;
  for (std::size_t i = 0; i < cloud.size(); i += stride)
  {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    Eigen::Matrix3d second = Eigen::Matrix3d::Zero();
    std::size_t k = 0;
    hash.forEachNear(cloud[i], [&](std::uint32_t j) {
      if ((cloud[j] - cloud[i]).squaredNorm() <= r2)
      {
        const Eigen::Vector3d q = pts[j];
        mean += q;
        second += q * q.transpose();
        ++k;
      }
      return k < 40;
    });
    if (k < 8)
    {
      continue;
    }
    mean /= static_cast<double>(k);
    const Eigen::Matrix3d cov = second / static_cast<double>(k) - mean * mean.transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    const Eigen::Vector3d ev = eig.eigenvalues();
    // Planar: thin across, extended in two directions.
    if (!(ev(0) < 0.25 * ev(1)))
    {
      continue;
    }
    normals.push_back(eig.eigenvectors().col(0).normalized());
  }
  up = up0;
  for (double cone_deg : { 45.0, 30.0 })
  {
    const double limit = std::sin(cone_deg * kDegToRad);
    Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
    n_walls = 0;
    for (const auto& n : normals)
    {
      if (std::abs(n.dot(up)) < limit)
      {
        m += n * n.transpose();
        ++n_walls;
      }
    }
    if (n_walls < 20)
    {
      return false;
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(m);
    // Walls of at least two directions pin up down: the smallest eigenvalue is far below the middle one.
    if (!(eig.eigenvalues()(0) < 0.2 * eig.eigenvalues()(1)))
    {
      return false;
    }
    Eigen::Vector3d u = eig.eigenvectors().col(0).normalized();
    if (u.dot(up0) < 0.0)
    {
      u = -u;
    }
    up = u;
  }
  return true;
}

/// Least-squares plane (normal towards up) through the points within `dist` of the plane (n, d).
bool refit(const std::vector<Eigen::Vector3d>& pts, const Eigen::Vector3d& up, double dist, Eigen::Vector3d& n,
           double& d)
{
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  std::size_t count = 0;
  for (const auto& p : pts)
  {
    if (std::abs(n.dot(p) + d) <= dist)
    {
      mean += p;
      ++count;
    }
  }
  if (count < 3)
  {
    return false;
  }
  mean /= static_cast<double>(count);
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : pts)
  {
    if (std::abs(n.dot(p) + d) <= dist)
    {
      cov += (p - mean) * (p - mean).transpose();
    }
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  Eigen::Vector3d m = eig.eigenvectors().col(0);
  if (!m.allFinite())
  {
    return false;
  }
  if (m.dot(up) < 0.0)
  {
    m = -m;
  }
  n = m.normalized();
  d = -n.dot(mean);
  return true;
}

struct Candidate
{
  FloorPlane plane;
};

/**
 * PCL's plane model with an axis constraint, counting inliers (RANSAC's inner loop) straight from
 * the points. PCL 1.13 as Debian builds it (without SSE4.1) counts in countWithinDistanceStandard,
 * which copies each point into a 4-vector on the stack and loads it back whole: a failed
 * store-to-load forward per point, most of the floor stage's sample consensus time. The distance
 * here is that compiled code's float arithmetic in its order, |(a x + c z) + (b y + d)| (a 4-lane
 * product summed high half onto low), so every count, and so every plane, is PCL's.
 */
class PerpendicularPlaneModel : public pcl::SampleConsensusModelPerpendicularPlane<pcl::PointXYZ>
{
public:
  using pcl::SampleConsensusModelPerpendicularPlane<pcl::PointXYZ>::SampleConsensusModelPerpendicularPlane;

  std::size_t countWithinDistance(const Eigen::VectorXf& model_coefficients, const double threshold) const override
  {
    if (!isModelValid(model_coefficients))
    {
      return 0;
    }
    const float a = model_coefficients[0], b = model_coefficients[1], c = model_coefficients[2], d = model_coefficients[3];
    std::size_t n = 0;
    for (const auto i : *indices_)
    {
      const pcl::PointXYZ& p = (*input_)[static_cast<std::size_t>(i)];
      const float distance = (a * p.x + c * p.z) + (b * p.y + d);
      n += std::abs(distance) < threshold ? 1 : 0;
    }
    return n;
  }
};

/// What pcl::SACSegmentation::segment does with RANSAC, the model above (PCL's fixed seed) and
/// optimised coefficients, step by step: the plane's inliers and coefficients, or false when no
/// plane was found.
bool segmentPlane(const pcl::PointCloud<pcl::PointXYZ>::Ptr& cloud, const Eigen::Vector3f& axis, double eps_angle_rad,
                  double threshold, int max_iterations, pcl::Indices& inliers, Eigen::VectorXf& coefficients)
{
  const auto model = std::make_shared<PerpendicularPlaneModel>(cloud);
  model->setAxis(axis);
  model->setEpsAngle(eps_angle_rad);
  pcl::RandomSampleConsensus<pcl::PointXYZ> sac(model, threshold);
  sac.setMaxIterations(max_iterations);
  if (!sac.computeModel())
  {
    return false;
  }
  pcl::Indices found;
  sac.getInliers(found);
  Eigen::VectorXf raw(model->getModelSize());
  sac.getModelCoefficients(raw);
  coefficients.resize(model->getModelSize());
  model->optimizeModelCoefficients(found, raw, coefficients);
  model->selectWithinDistance(coefficients, threshold, inliers);
  return true;
}

/// Extracts up to max_planes planes within eps_deg of up; inliers are removed after each one. A
/// plane holding no more than last_above_inliers points ends the search: the ones after it hold
/// fewer still.
std::vector<Candidate> extractPlanes(pcl::PointCloud<pcl::PointXYZ>::Ptr cloud, const FloorDetectorConfig& cfg,
                                     double eps_deg, int max_planes, std::size_t last_above_inliers = 0)
{
  std::vector<Candidate> out;
  const Eigen::Vector3d up = cfg.up_axis.normalized();
  const std::size_t needed = std::max<std::size_t>(
      cfg.min_inliers, static_cast<std::size_t>(std::ceil(cfg.min_inlier_fraction * static_cast<double>(cloud->size()))));
  for (int k = 0; k < max_planes && cloud->size() >= needed; ++k)
  {
    pcl::Indices inliers;
    Eigen::VectorXf coefficients;
    if (!segmentPlane(cloud, up.cast<float>(), eps_deg * kDegToRad, cfg.distance_threshold_m, cfg.max_iterations, inliers,
                      coefficients) ||
        inliers.size() < needed || coefficients.size() != 4)
    {
      break;
    }
    Eigen::Vector3d n(coefficients[0], coefficients[1], coefficients[2]);
    double d = coefficients[3];
    const double norm = n.norm();
    if (!(norm > 0.0) || !std::isfinite(d))
    {
      break;
    }
    n /= norm;
    d /= norm;
    if (n.dot(up) < 0.0)
    {
      n = -n;
      d = -d;
    }
    Candidate c;
    c.plane.normal = n;
    c.plane.d = d;
    c.plane.tilt_deg = tiltDeg(n, up);
    c.plane.n_inliers = inliers.size();
    // The refit may leave the cone slightly; beyond the tolerance the plane is not a candidate
    // but its inliers still go.
    if (c.plane.tilt_deg <= eps_deg + kRefitToleranceDeg)
    {
      out.push_back(c);
    }
    if (inliers.size() <= last_above_inliers)
    {
      break;
    }
    std::vector<char> drop(cloud->size(), 0);
    for (const auto i : inliers)
    {
      drop[static_cast<std::size_t>(i)] = 1;
    }
    pcl::PointCloud<pcl::PointXYZ>::Ptr rest(new pcl::PointCloud<pcl::PointXYZ>);
    rest->points.reserve(cloud->size() - inliers.size());
    for (std::size_t i = 0; i < cloud->size(); ++i)
    {
      if (!drop[i])
      {
        rest->points.push_back(cloud->points[i]);
      }
    }
    rest->width = static_cast<std::uint32_t>(rest->points.size());
    rest->height = 1;
    cloud = rest;
  }
  return out;
}
/// Sets below_fraction and drops candidates with too many points beneath them; returns how many went.
std::size_t keepFloorLike(std::vector<Candidate>& candidates, const pcl::PointCloud<pcl::PointXYZ>& cloud,
                          const FloorDetectorConfig& cfg)
{
  for (auto& c : candidates)
  {
    std::size_t below = 0;
    for (const auto& p : cloud.points)
    {
      if (c.plane.normal.dot(Eigen::Vector3d(p.x, p.y, p.z)) + c.plane.d < -cfg.below_margin_m)
      {
        ++below;
      }
    }
    c.plane.below_fraction = cloud.empty() ? 0.0 : static_cast<double>(below) / static_cast<double>(cloud.size());
  }
  const auto kept_end = std::remove_if(candidates.begin(), candidates.end(), [&](const Candidate& c) {
    return c.plane.below_fraction > cfg.max_below_fraction;
  });
  const std::size_t n_dropped = static_cast<std::size_t>(candidates.end() - kept_end);
  candidates.erase(kept_end, candidates.end());
  return n_dropped;
}

/// Every stride-th point, at most max_points of them, as a PCL cloud (a fixed, deterministic sample).
pcl::PointCloud<pcl::PointXYZ>::Ptr sampleCloud(const PointList& points, std::size_t max_points)
{
  const std::size_t stride = std::max<std::size_t>(1, (points.size() + max_points - 1) / max_points);
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  cloud->points.reserve(points.size() / stride + 1);
  for (std::size_t i = 0; i < points.size(); i += stride)
  {
    cloud->points.emplace_back(points[i].x(), points[i].y(), points[i].z());
  }
  cloud->width = static_cast<std::uint32_t>(cloud->points.size());
  cloud->height = 1;
  return cloud;
}

/// The two best floor-like planes within kWideConeDeg of up, most inliers first; only the first when
/// it holds no more than last_above_inliers points.
std::vector<Candidate> wideFloorPlanes(const pcl::PointCloud<pcl::PointXYZ>::Ptr& cloud, const FloorDetectorConfig& cfg,
                                       std::size_t last_above_inliers = 0)
{
  std::vector<Candidate> wide = extractPlanes(cloud, cfg, kWideConeDeg, 2, last_above_inliers);
  keepFloorLike(wide, *cloud, cfg);
  std::sort(wide.begin(), wide.end(),
            [](const Candidate& a, const Candidate& b) { return a.plane.n_inliers > b.plane.n_inliers; });
  return wide;
}
}  // namespace

Eigen::Vector3d axisFromString(const std::string& name)
{
  std::string s = name;
  double sign = 1.0;
  if (!s.empty() && (s[0] == '+' || s[0] == '-'))
  {
    sign = s[0] == '-' ? -1.0 : 1.0;
    s = s.substr(1);
  }
  if (s == "x" || s == "X")
  {
    return sign * Eigen::Vector3d::UnitX();
  }
  if (s == "y" || s == "Y")
  {
    return sign * Eigen::Vector3d::UnitY();
  }
  if (s == "z" || s == "Z")
  {
    return sign * Eigen::Vector3d::UnitZ();
  }
  throw std::invalid_argument("axis must be one of x, -x, y, -y, z, -z; got '" + name + "'");
}

void FloorDetectorConfig::validate() const
{
  if (!up_axis.allFinite() || up_axis.norm() < 1e-9)
  {
    throw std::invalid_argument("FloorDetectorConfig: up_axis must be a finite non-zero vector");
  }
  if (!(max_tilt_deg > 0.0 && max_tilt_deg < 90.0))
  {
    throw std::invalid_argument("FloorDetectorConfig: max_tilt_deg must be in (0, 90)");
  }
  if (!(distance_threshold_m > 0.0) || !std::isfinite(distance_threshold_m))
  {
    throw std::invalid_argument("FloorDetectorConfig: distance_threshold_m must be finite and > 0");
  }
  if (max_iterations < 1 || max_planes < 1)
  {
    throw std::invalid_argument("FloorDetectorConfig: max_iterations and max_planes must be >= 1");
  }
  if (!(min_relative_support >= 0.0 && min_relative_support <= 1.0))
  {
    throw std::invalid_argument("FloorDetectorConfig: min_relative_support must be in [0, 1]");
  }
  if (min_inliers < 3)
  {
    throw std::invalid_argument("FloorDetectorConfig: min_inliers must be >= 3");
  }
  if (!(max_below_fraction >= 0.0 && max_below_fraction <= 1.0) || !(below_margin_m >= 0.0))
  {
    throw std::invalid_argument("FloorDetectorConfig: max_below_fraction must be in [0, 1] and below_margin_m >= 0");
  }
  if (!(min_inlier_fraction >= 0.0 && min_inlier_fraction <= 1.0) || !(low_quantile >= 0.0 && low_quantile < 0.5))
  {
    throw std::invalid_argument("FloorDetectorConfig: min_inlier_fraction must be in [0, 1], low_quantile in [0, 0.5)");
  }
  if (!(min_contrast >= 0.0) || !std::isfinite(min_contrast))
  {
    throw std::invalid_argument("FloorDetectorConfig: min_contrast must be finite and >= 0");
  }
  if (!(tilt_step_deg > 0.0 && tilt_step_deg <= 5.0))
  {
    throw std::invalid_argument("FloorDetectorConfig: tilt_step_deg must be in (0, 5]");
  }
  if (max_fit_points < 3)
  {
    throw std::invalid_argument("FloorDetectorConfig: max_fit_points must be >= 3");
  }
}

FloorDetector::FloorDetector(const FloorDetectorConfig& config) : config_(config)
{
  config_.validate();
  config_.up_axis.normalize();
}

FloorResult FloorDetector::detect(const PointList& points) const
{
  // The envelope first: it is where sparse floors show, and at 100k points it costs ~10 ms where
  // sample consensus over a dozen planes costs ~350 ms.
  FloorResult envelope = detectByEnvelope(points);
  if (envelope.found)
  {
    return tiltedBeyondTheLimit(points, envelope);
  }
  if (envelope.reason.find("too few points") != std::string::npos)
  {
    return envelope;
  }
  // A tilted floor (walls or a better-supported envelope far outside the cone) stays an answer.
  if (std::isfinite(envelope.best_plane_tilt_deg) &&
      envelope.best_plane_tilt_deg > config_.max_tilt_deg + kRefitToleranceDeg)
  {
    return envelope;
  }
  FloorResult result = detectByConsensus(points);
  if (!result.found)
  {
    result.reason = envelope.reason + "; sample consensus: " + result.reason;
  }
  return result;
}

FloorResult FloorDetector::tiltedBeyondTheLimit(const PointList& points, const FloorResult& envelope) const
{
  // The lower envelope cannot see past its cone: a floor tilted beyond max_tilt_deg shows as an
  // envelope at the cone's edge (the EuRoC cloud, tilted 21 deg, gave one at 14.5 deg). Sample
  // consensus in the wide cone, on a small sample, tells: a floor-like plane beyond the limit with
  // clearly more inliers than the envelope's floor means the floor is tilted too much.
  const pcl::PointCloud<pcl::PointXYZ>::Ptr cloud = sampleCloud(points, kTiltCheckPoints);
  const FloorPlane& floor = envelope.plane;
  std::size_t support = 0;
  for (const auto& p : cloud->points)
  {
    support += std::abs(floor.normal.dot(Eigen::Vector3d(p.x, p.y, p.z)) + floor.d) <= config_.distance_threshold_m;
  }
  // A plane that cannot outweigh the envelope's floor ends the search (half the cost at 100k points).
  const auto enough = static_cast<std::size_t>(kTiltCheckSupportRatio * static_cast<double>(support));
  const std::vector<Candidate> wide = wideFloorPlanes(cloud, config_, enough);
  for (const auto& w : wide)
  {
    if (w.plane.tilt_deg > config_.max_tilt_deg + kRefitToleranceDeg &&
        static_cast<double>(w.plane.n_inliers) > kTiltCheckSupportRatio * static_cast<double>(support))
    {
      FloorResult result;
      result.best_plane_tilt_deg = w.plane.tilt_deg;
      result.n_candidates = envelope.n_candidates;
      char buf[320];
      std::snprintf(buf, sizeof(buf),
                    "no floor plane within %.1f deg of the up axis: a floor-like plane tilted %.1f deg holds %zu of "
                    "%zu sampled points, the lowest plane within the limit (%.1f deg) %zu",
                    config_.max_tilt_deg, w.plane.tilt_deg, w.plane.n_inliers, cloud->size(), floor.tilt_deg, support);
      result.reason = buf;
      return result;
    }
  }
  return envelope;
}

FloorResult FloorDetector::detectByConsensus(const PointList& points) const
{
  FloorResult result;
  result.best_plane_tilt_deg = std::numeric_limits<double>::quiet_NaN();
  if (points.size() < config_.min_inliers)
  {
    result.reason = "too few points for a floor plane (" + std::to_string(points.size()) + " < " +
                    std::to_string(config_.min_inliers) + ")";
    return result;
  }
  const pcl::PointCloud<pcl::PointXYZ>::Ptr cloud = sampleCloud(points, config_.max_fit_points);
  std::vector<Candidate> candidates = extractPlanes(cloud, config_, config_.max_tilt_deg, config_.max_planes);
  result.n_candidates = candidates.size();
  const std::size_t n_rejected_below = keepFloorLike(candidates, *cloud, config_);
  // The best-supported floor-like plane within 45 deg: when it is tilted beyond the limit and
  // better supported than every candidate, the floor is tilted too much and the candidates are
  // planes cutting through walls or furniture.
  const std::vector<Candidate> wide = wideFloorPlanes(cloud, config_);
  std::size_t candidate_support = 0;
  for (const auto& c : candidates)
  {
    candidate_support = std::max(candidate_support, c.plane.n_inliers);
  }
  if (!wide.empty())
  {
    result.best_plane_tilt_deg = wide.front().plane.tilt_deg;
  }
  // Wide-cone planes within the limit are candidates too (RANSAC may have found them only there).
  for (const auto& w : wide)
  {
    if (w.plane.tilt_deg <= config_.max_tilt_deg + kRefitToleranceDeg)
    {
      candidates.push_back(w);
      candidate_support = std::max(candidate_support, w.plane.n_inliers);
    }
  }
  result.n_candidates = candidates.size();
  const bool too_tilted = !wide.empty() && wide.front().plane.tilt_deg > config_.max_tilt_deg + kRefitToleranceDeg &&
                          wide.front().plane.n_inliers > candidate_support;
  if (candidates.empty() || too_tilted)
  {
    char buf[320];
    if (!wide.empty())
    {
      std::snprintf(buf, sizeof(buf),
                    "no floor plane within %.1f deg of the up axis; the best-supported floor-like plane within %.0f deg "
                    "is tilted %.1f deg (%zu inliers)",
                    config_.max_tilt_deg, kWideConeDeg, wide.front().plane.tilt_deg, wide.front().plane.n_inliers);
    }
    else
    {
      std::snprintf(buf, sizeof(buf),
                    "no floor plane within %.1f deg of the up axis, and no floor-like plane with >= %zu inliers within "
                    "%.0f deg",
                    config_.max_tilt_deg, config_.min_inliers, kWideConeDeg);
    }
    result.reason = buf;
    if (n_rejected_below > 0)
    {
      result.reason += "; " + std::to_string(n_rejected_below) +
                       " candidate plane(s) within the tilt limit had too many points beneath them to be a floor";
    }
    return result;
  }
  std::size_t best_support = 0;
  for (const auto& c : candidates)
  {
    best_support = std::max(best_support, c.plane.n_inliers);
  }
  const double needed = config_.min_relative_support * static_cast<double>(best_support);
  const Candidate* floor = nullptr;
  for (const auto& c : candidates)
  {
    if (static_cast<double>(c.plane.n_inliers) + 1e-9 < needed)
    {
      continue;
    }
    if (!floor || c.plane.height() < floor->plane.height())
    {
      floor = &c;
    }
  }
  result.found = true;
  result.plane = floor->plane;
  result.best_plane_tilt_deg = floor->plane.tilt_deg;
  return result;
}

FloorResult FloorDetector::detectByEnvelope(const PointList& points) const
{
  FloorResult result;
  result.best_plane_tilt_deg = std::numeric_limits<double>::quiet_NaN();
  if (points.size() < config_.min_inliers)
  {
    result.reason = "too few points for a floor plane (" + std::to_string(points.size()) + " < " +
                    std::to_string(config_.min_inliers) + ")";
    return result;
  }
  const Eigen::Vector3d up = config_.up_axis;
  auto subsample = [&](std::size_t max_points) {
    const std::size_t stride = (points.size() + max_points - 1) / max_points;
    std::vector<Eigen::Vector3d> out;
    out.reserve(points.size() / stride + 1);
    for (std::size_t i = 0; i < points.size(); i += stride)
    {
      out.push_back(points[i].cast<double>());
    }
    return out;
  };
  const std::vector<Eigen::Vector3d> fit = subsample(config_.max_fit_points);
  const std::vector<Eigen::Vector3d> coarse = subsample(std::min(kSearchPoints, config_.max_fit_points));
  const double thr = config_.distance_threshold_m;
  const double width = 2.0 * thr;
  const double n_fit = static_cast<double>(fit.size());
  const std::size_t needed =
      std::max(config_.min_inliers, static_cast<std::size_t>(std::ceil(config_.min_inlier_fraction * n_fit)));

  // The walls tell up best when the floor is barely seen; a dense floor tells it better still.
  Eigen::Vector3d wall_up;
  std::size_t n_walls = 0;
  const bool has_walls = upFromWalls(fit, up, config_.wall_radius_m, wall_up, n_walls);
  const double wall_tilt = has_walls ? tiltDeg(wall_up, up) : std::numeric_limits<double>::quiet_NaN();
  const Envelope inside = searchEnvelope(coarse, fit, up, config_.max_tilt_deg, config_.tilt_step_deg, width,
                                         config_.low_quantile);
  result.n_candidates = 1;
  if (has_walls)
  {
    result.best_plane_tilt_deg = wall_tilt;
    if (wall_tilt > config_.max_tilt_deg + kRefitToleranceDeg)
    {
      char buf[320];
      std::snprintf(buf, sizeof(buf),
                    "no floor plane within %.1f deg of the up axis: the walls (%zu planar patches) stand %.1f deg off "
                    "it, so the floor is tilted %.1f deg",
                    config_.max_tilt_deg, n_walls, wall_tilt, wall_tilt);
      result.reason = buf;
      return result;
    }
  }
  else
  {
    // No walls to ask: a lower envelope far outside the cone that holds more points is a tilted floor.
    const Envelope wide = searchEnvelope(coarse, fit, up, kWideConeDeg, 1.0, width, config_.low_quantile);
    result.best_plane_tilt_deg = wide.tilt_deg;
    if (wide.tilt_deg > config_.max_tilt_deg + kRefitToleranceDeg &&
        static_cast<double>(wide.count) > kTiltedSupportRatio * static_cast<double>(inside.count) && wide.count >= needed)
    {
      char buf[320];
      std::snprintf(buf, sizeof(buf),
                    "no floor plane within %.1f deg of the up axis; the floor-like plane with the most points within "
                    "%.0f deg is tilted %.1f deg (%zu points against %zu within the limit)",
                    config_.max_tilt_deg, kWideConeDeg, wide.tilt_deg, wide.count, inside.count);
      result.reason = buf;
      return result;
    }
  }

  // Refit by least squares: the points within the threshold of the envelope's slab, then half of it.
  Eigen::Vector3d n = inside.normal;
  double d = -(inside.low + thr);
  bool ok = refit(fit, up, thr, n, d) && refit(fit, up, 0.5 * thr, n, d);
  if (!ok || tiltDeg(n, up) > config_.max_tilt_deg + kRefitToleranceDeg)
  {
    n = inside.normal;
    d = -(inside.low + thr);
  }
  if (has_walls && std::acos(std::min(1.0, n.dot(wall_up))) / kDegToRad > config_.max_wall_disagreement_deg)
  {
    // The fitted plane leans against the walls: it is a slab of wall bottoms, not a floor. The
    // floor is perpendicular to the walls, at their lower envelope.
    std::vector<double> heights;
    const Envelope e = lowerEnvelope(fit, wall_up, width, config_.low_quantile, heights);
    n = wall_up;
    d = -(e.low + thr);
    // Centre the plane on the points of its slab.
    double sum = 0.0;
    std::size_t k = 0;
    for (double h : heights)
    {
      if (h >= e.low && h <= e.low + width)
      {
        sum += h;
        ++k;
      }
    }
    if (k > 0)
    {
      d = -sum / static_cast<double>(k);
    }
  }
  std::size_t n_in = 0, n_under = 0, n_below = 0;
  for (const auto& p : fit)
  {
    const double h = n.dot(p) + d;
    n_in += std::abs(h) <= thr ? 1 : 0;
    n_under += (h < -thr && h >= -thr - width) ? 1 : 0;
    n_below += h < -config_.below_margin_m ? 1 : 0;
  }
  FloorPlane plane;
  plane.normal = n;
  plane.d = d;
  plane.tilt_deg = tiltDeg(n, up);
  plane.n_inliers = n_in;
  plane.below_fraction = static_cast<double>(n_below) / n_fit;
  char buf[320];
  if (n_in < needed)
  {
    std::snprintf(buf, sizeof(buf),
                  "no floor plane within %.1f deg of the up axis: the lowest plane holds %zu points (needs %zu)",
                  config_.max_tilt_deg, n_in, needed);
    result.reason = buf;
    return result;
  }
  if (!has_walls && static_cast<double>(n_in) < config_.min_contrast * static_cast<double>(n_under))
  {
    std::snprintf(buf, sizeof(buf),
                  "no floor plane within %.1f deg of the up axis: the lowest plane (%zu points) has %zu points just "
                  "beneath it, no floor edge (a cloud without a floor?)",
                  config_.max_tilt_deg, n_in, n_under);
    result.reason = buf;
    return result;
  }
  if (plane.below_fraction > config_.max_below_fraction)
  {
    std::snprintf(buf, sizeof(buf),
                  "no floor plane within %.1f deg of the up axis: %.0f%% of the points lie more than %.2f m under the "
                  "lowest plane",
                  config_.max_tilt_deg, 100.0 * plane.below_fraction, config_.below_margin_m);
    result.reason = buf;
    return result;
  }
  result.found = true;
  result.plane = plane;
  result.best_plane_tilt_deg = plane.tilt_deg;
  return result;
}

Eigen::Isometry3d alignToFloor(const FloorPlane& plane)
{
  const Eigen::Vector3d n = plane.normal.normalized();
  const Eigen::Quaterniond q = Eigen::Quaterniond::FromTwoVectors(n, Eigen::Vector3d::UnitZ());
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = q.toRotationMatrix();
  // After the rotation the floor satisfies z + d / |n| = 0, so shift by d.
  t.translation() = Eigen::Vector3d(0.0, 0.0, plane.d / plane.normal.norm());
  return t;
}

PointList transformPoints(const PointList& points, const Eigen::Isometry3d& transform)
{
  PointList out;
  transformPoints(points, transform, out);
  return out;
}

void transformPoints(const PointList& points, const Eigen::Isometry3d& transform, PointList& out)
{
  const Eigen::Isometry3f t = transform.cast<float>();
  out.resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
  {
    out[i] = t * points[i];
  }
}

}  // namespace sparse_nav
