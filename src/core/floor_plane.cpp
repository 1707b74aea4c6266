#include "sparse_nav/core/floor_plane.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <vector>

#include <pcl/ModelCoefficients.h>
#include <pcl/PointIndices.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/method_types.h>
#include <pcl/sample_consensus/model_types.h>
#include <pcl/segmentation/sac_segmentation.h>

namespace sparse_nav
{
namespace
{
constexpr double kDegToRad = M_PI / 180.0;
constexpr double kRefitToleranceDeg = 0.5;
constexpr double kWideConeDeg = 45.0;

struct Candidate
{
  FloorPlane plane;
};

double tiltDeg(const Eigen::Vector3d& normal, const Eigen::Vector3d& up)
{
  const double c = std::min(1.0, std::abs(normal.normalized().dot(up.normalized())));
  return std::acos(c) / kDegToRad;
}

/// Extracts up to max_planes planes within eps_deg of up; inliers are removed after each one.
std::vector<Candidate> extractPlanes(pcl::PointCloud<pcl::PointXYZ>::Ptr cloud, const FloorDetectorConfig& cfg,
                                     double eps_deg, int max_planes)
{
  std::vector<Candidate> out;
  const Eigen::Vector3d up = cfg.up_axis.normalized();
  pcl::SACSegmentation<pcl::PointXYZ> seg;
  seg.setOptimizeCoefficients(true);
  seg.setModelType(pcl::SACMODEL_PERPENDICULAR_PLANE);
  seg.setMethodType(pcl::SAC_RANSAC);
  seg.setAxis(up.cast<float>());
  seg.setEpsAngle(eps_deg * kDegToRad);
  seg.setDistanceThreshold(cfg.distance_threshold_m);
  seg.setMaxIterations(cfg.max_iterations);
  const std::size_t needed = std::max<std::size_t>(
      cfg.min_inliers, static_cast<std::size_t>(std::ceil(cfg.min_inlier_fraction * static_cast<double>(cloud->size()))));
  for (int k = 0; k < max_planes && cloud->size() >= needed; ++k)
  {
    pcl::ModelCoefficients coefficients;
    pcl::PointIndices inliers;
    seg.setInputCloud(cloud);
    seg.segment(inliers, coefficients);
    if (inliers.indices.size() < needed || coefficients.values.size() != 4)
    {
      break;
    }
    Eigen::Vector3d n(coefficients.values[0], coefficients.values[1], coefficients.values[2]);
    double d = coefficients.values[3];
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
    c.plane.n_inliers = inliers.indices.size();
    // The refit may leave the cone slightly; beyond the tolerance the plane is not a candidate
    // but its inliers still go.
    if (c.plane.tilt_deg <= eps_deg + kRefitToleranceDeg)
    {
      out.push_back(c);
    }
    std::vector<char> drop(cloud->size(), 0);
    for (int i : inliers.indices)
    {
      drop[static_cast<std::size_t>(i)] = 1;
    }
    pcl::PointCloud<pcl::PointXYZ>::Ptr rest(new pcl::PointCloud<pcl::PointXYZ>);
    rest->points.reserve(cloud->size() - inliers.indices.size());
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
  if (min_inliers < 3)
  {
    throw std::invalid_argument("FloorDetectorConfig: min_inliers must be >= 3");
  }
  if (!(min_relative_support >= 0.0 && min_relative_support <= 1.0))
  {
    throw std::invalid_argument("FloorDetectorConfig: min_relative_support must be in [0, 1]");
  }
  if (!(max_below_fraction >= 0.0 && max_below_fraction <= 1.0) || !(below_margin_m >= 0.0))
  {
    throw std::invalid_argument("FloorDetectorConfig: max_below_fraction must be in [0, 1] and below_margin_m >= 0");
  }
  if (!(min_inlier_fraction >= 0.0 && min_inlier_fraction <= 1.0))
  {
    throw std::invalid_argument("FloorDetectorConfig: min_inlier_fraction must be in [0, 1]");
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
  FloorResult result;
  result.best_plane_tilt_deg = std::numeric_limits<double>::quiet_NaN();
  if (points.size() < config_.min_inliers)
  {
    result.reason = "too few points for a floor plane (" + std::to_string(points.size()) + " < " +
                    std::to_string(config_.min_inliers) + ")";
    return result;
  }
  const std::size_t stride = (points.size() + config_.max_fit_points - 1) / config_.max_fit_points;
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  cloud->points.reserve(points.size() / stride + 1);
  for (std::size_t i = 0; i < points.size(); i += stride)
  {
    const auto& p = points[i];
    cloud->points.emplace_back(p.x(), p.y(), p.z());
  }
  cloud->width = static_cast<std::uint32_t>(cloud->points.size());
  cloud->height = 1;

  std::vector<Candidate> candidates = extractPlanes(cloud, config_, config_.max_tilt_deg, config_.max_planes);
  result.n_candidates = candidates.size();
  const std::size_t n_rejected_below = keepFloorLike(candidates, *cloud, config_);
  // The best-supported floor-like plane within 45 deg: when it is tilted beyond the limit and
  // better supported than every candidate, the floor is tilted too much and the candidates are
  // planes cutting through walls or furniture.
  std::vector<Candidate> wide = extractPlanes(cloud, config_, kWideConeDeg, 2);
  keepFloorLike(wide, *cloud, config_);
  std::sort(wide.begin(), wide.end(),
            [](const Candidate& a, const Candidate& b) { return a.plane.n_inliers > b.plane.n_inliers; });
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
  const Eigen::Isometry3f t = transform.cast<float>();
  PointList out;
  out.reserve(points.size());
  for (const auto& p : points)
  {
    out.push_back(t * p);
  }
  return out;
}

}  // namespace sparse_nav
