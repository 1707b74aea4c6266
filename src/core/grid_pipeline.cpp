#include "sparse_nav/core/grid_pipeline.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <limits>
#include <stdexcept>
#include <vector>

namespace sparse_nav
{
namespace
{
class StageTimer
{
public:
  explicit StageTimer(std::map<std::string, double>& out) : out_(out), last_(Clock::now()) {}
  void lap(const std::string& name)
  {
    const auto now = Clock::now();
    out_[name] += std::chrono::duration<double, std::milli>(now - last_).count();
    last_ = now;
  }

private:
  using Clock = std::chrono::steady_clock;
  std::map<std::string, double>& out_;
  Clock::time_point last_;
};
}  // namespace

void GridPipelineConfig::validate() const
{
  if (!(metres_per_unit > 0.0) || !std::isfinite(metres_per_unit))
  {
    throw std::invalid_argument("GridPipelineConfig: metres_per_unit must be finite and > 0");
  }
  if (!std::isfinite(floor_clearance_m) || !std::isfinite(ceiling_height_m) || !(ceiling_height_m > floor_clearance_m))
  {
    throw std::invalid_argument("GridPipelineConfig: ceiling_height_m must be finite and above floor_clearance_m");
  }
  guard.validate();
  density.validate();
  voxel.validate();
  floor.validate();
  octree.validate();
  grid.validate();
}

GridPipeline::GridPipeline(const GridPipelineConfig& config)
  : config_((config.validate(), config))
  , guard_(config.guard)
  , density_(config.density)
  , voxel_(config.voxel)
  , floor_detector_(config.floor)
  , builder_(config.grid)
{
  if (config_.octree_enabled)
  {
    octree_ = std::make_unique<OctreeMap>(config_.octree);
  }
}

GridPipeline::~GridPipeline() = default;

void GridPipeline::reset()
{
  has_floor_ = false;
  floor_ = FloorPlane();
  builder_.reset();
  if (octree_)
  {
    octree_->clear();
  }
}

GridPipelineResult GridPipeline::process(const PointList& slam_points, const PointList& camera_positions)
{
  GridPipelineResult r;
  r.n_points = slam_points.size();
  const auto t0 = std::chrono::steady_clock::now();
  StageTimer timer(r.stages_ms);
  try
  {
    // Guard in SLAM units, then scale to metres.
    PointList points = guard_.apply(slam_points, &r.guard);
    const float s = static_cast<float>(config_.metres_per_unit);
    for (auto& p : points)
    {
      p *= s;
    }
    timer.lap("guard");
    points = density_.apply(points, &r.density);
    timer.lap("density");
    if (config_.voxel_enabled)
    {
      points = voxel_.apply(points, &r.voxel);
    }
    else
    {
      r.voxel.n_in = r.voxel.n_out = points.size();
    }
    timer.lap("voxel");
    if (points.empty())
    {
      r.status = "empty cloud: no points left after the guard and filters (" + std::to_string(r.guard.n_non_finite) +
                 " non-finite, " + std::to_string(r.guard.n_out_of_range) + " out of range)";
      r.total_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      return r;
    }

    if (!has_floor_ || !config_.keep_floor)
    {
      r.floor = floor_detector_.detect(points);
      timer.lap("floor");
      if (!r.floor.found)
      {
        r.status = r.floor.reason;
        r.total_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        return r;
      }
      if (has_floor_)
      {
        builder_.reset();
        if (octree_)
        {
          octree_->clear();
        }
      }
      has_floor_ = true;
      floor_ = r.floor.plane;
    }
    else
    {
      r.floor.found = true;
      r.floor.plane = floor_;
      r.floor.best_plane_tilt_deg = floor_.tilt_deg;
      timer.lap("floor");
    }
    r.slam_to_map = alignToFloor(floor_);
    points = transformPoints(points, r.slam_to_map);
    std::vector<Eigen::Vector3d> cameras;
    if (camera_positions.empty())
    {
      cameras.push_back(r.slam_to_map * Eigen::Vector3d::Zero());
    }
    for (const auto& c : camera_positions)
    {
      if (c.allFinite())
      {
        cameras.push_back(r.slam_to_map * (c.cast<double>() * config_.metres_per_unit));
      }
    }
    if (cameras.empty())
    {
      cameras.push_back(r.slam_to_map * Eigen::Vector3d::Zero());
    }
    std::vector<std::size_t> nearest(points.size(), 0);
    if (cameras.size() > 1)
    {
      for (std::size_t i = 0; i < points.size(); ++i)
      {
        double best = std::numeric_limits<double>::infinity();
        for (std::size_t c = 0; c < cameras.size(); ++c)
        {
          const double d = (points[i].cast<double>() - cameras[c]).squaredNorm();
          if (d < best)
          {
            best = d;
            nearest[i] = c;
          }
        }
      }
    }
    timer.lap("align");

    if (octree_)
    {
      for (std::size_t c = 0; c < cameras.size(); ++c)
      {
        PointList group;
        for (std::size_t i = 0; i < points.size(); ++i)
        {
          if (nearest[i] == c)
          {
            group.push_back(points[i]);
          }
        }
        const OctreeInsertStats st = octree_->insert(group, cameras[c]);
        r.octree.n_inserted += st.n_inserted;
        r.octree.n_out_of_range += st.n_out_of_range;
        r.octree.origin_ok = r.octree.origin_ok && st.origin_ok;
      }
      timer.lap("octree");
    }

    // Band removal, 2D slice, and the part of each camera ray inside the band.
    const double z_lo = config_.floor_clearance_m, z_hi = config_.ceiling_height_m;
    PointList2D obstacles;
    obstacles.reserve(points.size());
    std::vector<FreeRay> rays;
    rays.reserve(points.size());
    for (std::size_t i = 0; i < points.size(); ++i)
    {
      const Eigen::Vector3d p = points[i].cast<double>();
      if (p.z() < z_lo)
      {
        ++r.n_floor_band;
      }
      else if (p.z() > z_hi)
      {
        ++r.n_ceiling_band;
      }
      else
      {
        obstacles.emplace_back(p.x(), p.y());
      }
      const Eigen::Vector3d& c = cameras[nearest[i]];
      const double dz = p.z() - c.z();
      double t0r = 0.0, t1r = 1.0;
      if (std::abs(dz) < 1e-12)
      {
        if (c.z() < z_lo || c.z() > z_hi)
        {
          continue;
        }
      }
      else
      {
        double ta = (z_lo - c.z()) / dz, tb = (z_hi - c.z()) / dz;
        if (ta > tb)
        {
          std::swap(ta, tb);
        }
        t0r = std::max(t0r, ta);
        t1r = std::min(t1r, tb);
        if (t0r > t1r)
        {
          continue;
        }
      }
      const Eigen::Vector3d a = c + t0r * (p - c), b = c + t1r * (p - c);
      rays.push_back(FreeRay{ a.head<2>(), b.head<2>() });
    }
    r.n_obstacles = obstacles.size();
    timer.lap("slice");
    r.grid = builder_.update(obstacles, rays);
    timer.lap("grid");
    r.ok = r.grid.ok;
    char buf[256];
    std::snprintf(buf, sizeof(buf), "%zu points -> %zu filtered -> %zu obstacles; floor tilt %.1f deg; %s",
                  r.n_points, points.size(), r.n_obstacles, floor_.tilt_deg, r.grid.status.c_str());
    r.status = buf;
  }
  catch (const std::exception& e)
  {
    r.ok = false;
    r.status = std::string("pipeline error: ") + e.what();
  }
  catch (...)
  {
    r.ok = false;
    r.status = "pipeline error: unknown exception";
  }
  r.total_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace sparse_nav
