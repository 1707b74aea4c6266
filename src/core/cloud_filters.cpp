#include "sparse_nav/core/cloud_filters.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <unordered_map>

#include <pcl/filters/voxel_grid.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include "spatial_hash.h"

namespace sparse_nav
{
namespace
{
pcl::PointCloud<pcl::PointXYZ>::Ptr toPcl(const PointList& points)
{
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  cloud->points.resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
  {
    cloud->points[i].x = points[i].x();
    cloud->points[i].y = points[i].y();
    cloud->points[i].z = points[i].z();
  }
  cloud->width = static_cast<std::uint32_t>(points.size());
  cloud->height = 1;
  cloud->is_dense = true;
  return cloud;
}

void appendFromPcl(const pcl::PointCloud<pcl::PointXYZ>& cloud, PointList& out)
{
  out.reserve(out.size() + cloud.size());
  for (const auto& p : cloud.points)
  {
    out.emplace_back(p.x, p.y, p.z);
  }
}

/// The points whose keep flag is set, in their order.
PointList keptPoints(const PointList& points, const std::vector<char>& keep)
{
  PointList out;
  out.reserve(static_cast<std::size_t>(std::count(keep.begin(), keep.end(), 1)));
  for (std::size_t i = 0; i < points.size(); ++i)
  {
    if (keep[i])
    {
      out.push_back(points[i]);
    }
  }
  return out;
}
}  // namespace


void PointGuardConfig::validate() const
{
  if (!(max_abs_coordinate > 0.0) || !std::isfinite(max_abs_coordinate))
  {
    throw std::invalid_argument("PointGuardConfig: max_abs_coordinate must be finite and > 0");
  }
}

PointGuard::PointGuard(const PointGuardConfig& config) : config_(config)
{
  config_.validate();
}

PointList PointGuard::apply(const PointList& points, PointGuardStats* stats) const
{
  PointGuardStats s;
  s.n_in = points.size();
  PointList out;
  out.reserve(points.size());
  const float limit = static_cast<float>(config_.max_abs_coordinate);
  for (const auto& p : points)
  {
    if (!p.allFinite())
    {
      ++s.n_non_finite;
      continue;
    }
    if (std::abs(p.x()) > limit || std::abs(p.y()) > limit || std::abs(p.z()) > limit)
    {
      ++s.n_out_of_range;
      continue;
    }
    out.push_back(p);
  }
  s.n_out = out.size();
  if (stats)
  {
    *stats = s;
  }
  return out;
}


DensityMethod densityMethodFromString(const std::string& name)
{
  if (name == "none")
  {
    return DensityMethod::kNone;
  }
  if (name == "radius")
  {
    return DensityMethod::kRadiusOutlier;
  }
  if (name == "ipcl")
  {
    return DensityMethod::kIpcl;
  }
  throw std::invalid_argument("density method must be one of none, radius, ipcl; got '" + name + "'");
}

void DensityFilterConfig::validate() const
{
  if (!(radius_m > 0.0) || !std::isfinite(radius_m))
  {
    throw std::invalid_argument("DensityFilterConfig: radius_m must be finite and > 0");
  }
  if (min_neighbors < 0)
  {
    throw std::invalid_argument("DensityFilterConfig: min_neighbors must be >= 0");
  }
  if (ipcl_rounds < 1)
  {
    throw std::invalid_argument("DensityFilterConfig: ipcl_rounds must be >= 1");
  }
}

DensityFilter::DensityFilter(const DensityFilterConfig& config) : config_(config)
{
  config_.validate();
}

PointList DensityFilter::apply(const PointList& points, DensityFilterStats* stats) const
{
  DensityFilterStats s;
  s.n_in = points.size();
  PointList out;
  if (config_.method == DensityMethod::kNone || config_.min_neighbors == 0 || points.empty())
  {
    out = points;
  }
  else if (config_.method == DensityMethod::kIpcl)
  {
    out = applyIpcl(points, &s);
  }
  else
  {
    out = applyRadiusOutlier(points);
    s.rounds_run = 1;
  }
  s.n_out = out.size();
  if (stats)
  {
    *stats = s;
  }
  return out;
}

PointList DensityFilter::applyRadiusOutlier(const PointList& points) const
{
  // PCL's RadiusOutlierRemoval rule (keep points with >= min_neighbors others within radius_m),
  // counted in a uniform hash that stops at min_neighbors: a k-d tree radius search returns every
  // neighbour, which in dense clouds costs ten times more.
  const SpatialHash3 hash(config_.radius_m, points);
  const std::vector<char> keep = hash.hasNeighbours(points, static_cast<float>(config_.radius_m),
                                                    static_cast<std::size_t>(config_.min_neighbors));
  return keptPoints(points, keep);
}

PointList DensityFilter::applyIpcl(const PointList& points, DensityFilterStats* stats) const
{
  const double r = config_.radius_m;
  PointList alive = points;
  for (int round = 0; round < config_.ipcl_rounds && !alive.empty(); ++round)
  {
    ++stats->rounds_run;
    const SpatialHash3 hash(r, alive);
    const std::vector<char> keep =
        hash.hasNeighbours(alive, static_cast<float>(r), static_cast<std::size_t>(config_.min_neighbors));
    const std::size_t n_keep = static_cast<std::size_t>(std::count(keep.begin(), keep.end(), 1));
    if (n_keep == alive.size())
    {
      break;
    }
    alive = keptPoints(alive, keep);
  }
  return alive;
}


void VoxelFilterConfig::validate() const
{
  if (!(leaf_size_m > 0.0) || !std::isfinite(leaf_size_m))
  {
    throw std::invalid_argument("VoxelFilterConfig: leaf_size_m must be finite and > 0");
  }
}

VoxelFilter::VoxelFilter(const VoxelFilterConfig& config) : config_(config)
{
  config_.validate();
}

PointList VoxelFilter::apply(const PointList& points, VoxelFilterStats* stats) const
{
  VoxelFilterStats s;
  s.n_in = points.size();
  PointList out;
  if (points.empty())
  {
    s.n_chunks = 0;
    if (stats)
    {
      *stats = s;
    }
    return out;
  }
  const double leaf = config_.leaf_size_m;
  Eigen::Vector3d lo = points.front().cast<double>();
  Eigen::Vector3d hi = lo;
  for (const auto& p : points)
  {
    lo = lo.cwiseMin(p.cast<double>());
    hi = hi.cwiseMax(p.cast<double>());
  }
  // The same count PCL makes: (floor(max / leaf) - floor(min / leaf) + 1) per axis, in doubles.
  double n_voxels = 1.0;
  for (int a = 0; a < 3; ++a)
  {
    n_voxels *= std::floor(hi[a] / leaf) - std::floor(lo[a] / leaf) + 1.0;
  }
  const pcl::PointCloud<pcl::PointXYZ>::Ptr all = toPcl(points);
  pcl::VoxelGrid<pcl::PointXYZ> grid;
  grid.setLeafSize(static_cast<float>(leaf), static_cast<float>(leaf), static_cast<float>(leaf));
  // PCL's limit, with a margin for its float arithmetic.
  const double limit = 0.5 * static_cast<double>(std::numeric_limits<std::int32_t>::max());
  if (n_voxels <= limit)
  {
    pcl::PointCloud<pcl::PointXYZ> filtered;
    grid.setInputCloud(all);
    grid.filter(filtered);
    appendFromPcl(filtered, out);
  }
  else
  {
    // Blocks of 1024^3 voxels, aligned to leaf multiples so no voxel straddles two blocks.
    s.overflow_guarded = true;
    const double block = 1024.0;
    std::unordered_map<CellKey, std::vector<int>, CellKeyHash> blocks;
    for (std::size_t i = 0; i < points.size(); ++i)
    {
      const Eigen::Vector3d p = points[i].cast<double>();
      CellKey key{ static_cast<std::int64_t>(std::floor(std::floor(p.x() / leaf) / block)),
                   static_cast<std::int64_t>(std::floor(std::floor(p.y() / leaf) / block)),
                   static_cast<std::int64_t>(std::floor(std::floor(p.z() / leaf) / block)) };
      blocks[key].push_back(static_cast<int>(i));
    }
    s.n_chunks = blocks.size();
    pcl::PointCloud<pcl::PointXYZ>::Ptr part(new pcl::PointCloud<pcl::PointXYZ>);
    pcl::PointCloud<pcl::PointXYZ> filtered;
    for (const auto& entry : blocks)
    {
      part->points.clear();
      for (int i : entry.second)
      {
        part->points.push_back(all->points[static_cast<std::size_t>(i)]);
      }
      part->width = static_cast<std::uint32_t>(part->points.size());
      part->height = 1;
      grid.setInputCloud(part);
      grid.filter(filtered);
      appendFromPcl(filtered, out);
    }
  }
  s.n_out = out.size();
  if (stats)
  {
    *stats = s;
  }
  return out;
}

}  // namespace sparse_nav
