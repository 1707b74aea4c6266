#include "sparse_nav/core/grid_pipeline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <limits>
#include <stdexcept>
#include <utility>
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
  void restart() { last_ = Clock::now(); }

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
  guard.validate();
  voxel.validate();
  ground.validate();
  grid.validate();
}

GridPipeline::GridPipeline(const GridPipelineConfig& config)
  : config_((config.validate(), config))
  , guard_(config.guard)
  , voxel_(config.voxel, config.voxel_enabled)
  , ground_(config.ground)
  , builder_(config.grid)
{
}

GridPipeline::~GridPipeline() = default;

void GridPipeline::forgetLastCloud()
{
  voxel_.clear();
  ground_saw_last_cloud_ = false;
  builder_saw_last_ground_ = false;
}

void GridPipeline::reset()
{
  forgetLastCloud();
  ground_.reset();
  builder_.reset();
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
    r.voxel.n_in = points.size();
    const PointList& voxels = voxel_.apply(std::move(points));
    r.n_changed_points = voxel_.numChanged();
    r.voxel.n_out = voxels.size();
    timer.lap("voxel");
    if (voxels.empty())
    {
      ground_saw_last_cloud_ = false;
      r.status = "empty cloud: no points left after the guard and the voxel grid (" + std::to_string(r.guard.n_non_finite) +
                 " non-finite, " + std::to_string(r.guard.n_out_of_range) + " out of range)";
      r.total_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      return r;
    }
    std::vector<Eigen::Vector3d> cameras;
    for (const auto& c : camera_positions)
    {
      cameras.push_back(c.cast<double>() * config_.metres_per_unit);
    }
    const bool continues = ground_saw_last_cloud_ && !voxel_.rebuilt();
    ground_saw_last_cloud_ = true;
    GroundMapperResult g = ground_.process(voxels, cameras, continues ? &voxel_.previousIndex() : nullptr);
    for (const auto& kv : g.stages_ms)
    {
      r.stages_ms[kv.first] += kv.second;
    }
    r.floor = g.floor;
    r.density = g.density;
    if (!g.ok)
    {
      builder_saw_last_ground_ = false;
      r.status = g.status;
      r.total_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      return r;
    }
    if (g.floor_changed)
    {
      builder_.reset();
    }
    r.slam_to_map = g.to_output;
    r.octree = g.octree;
    r.n_floor_band = g.n_floor_band;
    r.n_ceiling_band = g.n_ceiling_band;
    r.n_freed = g.n_freed;
    r.n_obstacles = g.obstacles.size();
    PointList2D& obstacles = obstacles_xy_;
    obstacles.resize(g.obstacles.size());
    for (std::size_t i = 0; i < g.obstacles.size(); ++i)
    {
      obstacles[i] = g.obstacles[i].head<2>().cast<double>();
    }
    timer.restart();
    if (builder_saw_last_ground_ && g.incremental)
    {
      GridChange change;
      change.obstacles_removed = std::move(g.obstacles_removed_xy);
      change.obstacles_added = std::move(g.obstacles_added_xy);
      change.rays_removed = std::move(g.rays_removed);
      change.rays_added = std::move(g.rays_added);
      r.grid = builder_.update(obstacles, [this] { return ground_.rays(); }, change);
    }
    else
    {
      r.grid = builder_.update(obstacles, std::move(g.rays));
    }
    builder_saw_last_ground_ = r.grid.ok;
    timer.lap("grid");
    r.ok = r.grid.ok;
    char buf[256];
    std::snprintf(buf, sizeof(buf), "%zu points -> %zu voxels -> %zu dense -> %zu obstacles (%zu in free space); floor tilt %.1f deg; %s",
                  r.n_points, voxels.size(), g.density.n_out, r.n_obstacles, r.n_freed, g.floor.plane.tilt_deg, r.grid.status.c_str());
    r.status = buf;
  }
  catch (const std::exception& e)
  {
    forgetLastCloud();
    r.ok = false;
    r.status = std::string("pipeline error: ") + e.what();
  }
  catch (...)
  {
    forgetLastCloud();
    r.ok = false;
    r.status = "pipeline error: unknown exception";
  }
  r.total_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace sparse_nav
