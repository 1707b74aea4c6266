#include "sparse_nav/core/ground_mapper.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

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

void GroundMapperConfig::validate() const
{
  if (!std::isfinite(floor_clearance_m) || !std::isfinite(ceiling_height_m) || !(ceiling_height_m > floor_clearance_m))
  {
    throw std::invalid_argument("GroundMapperConfig: ceiling_height_m must be finite and above floor_clearance_m");
  }
  floor.validate();
  density.validate();
  octree.validate();
}

GroundMapper::GroundMapper(const GroundMapperConfig& config)
  : config_((config.validate(), config)), detector_(config.floor), density_(config.density)
{
  if (config_.octree_enabled)
  {
    octree_ = std::make_unique<OctreeMap>(config_.octree);
  }
}

GroundMapper::~GroundMapper() = default;

void GroundMapper::reset()
{
  has_floor_ = false;
  floor_ = FloorResult();
  if (octree_)
  {
    octree_->clear();
  }
}

GroundMapperResult GroundMapper::process(const PointList& input, const std::vector<Eigen::Vector3d>& cameras)
{
  GroundMapperResult r;
  StageTimer timer(r.stages_ms);
  if (!has_floor_ || !config_.keep_floor)
  {
    const FloorResult found = detector_.detect(input);
    if (found.found)
    {
      const bool moved = has_floor_ && (found.plane.normal != floor_.plane.normal || found.plane.d != floor_.plane.d);
      if (moved && config_.align_to_floor)
      {
        // The output frame follows the floor: what was built in the old one no longer fits.
        r.floor_changed = true;
        if (octree_)
        {
          octree_->clear();
        }
      }
      floor_ = found;
      has_floor_ = true;
    }
    else if (!has_floor_)
    {
      r.floor = found;
      r.status = found.reason;
      timer.lap("floor");
      return r;
    }
    else
    {
      r.floor_warning = found.reason;
    }
  }
  r.floor = floor_;
  timer.lap("floor");
  const PointList points = density_.apply(input, &r.density);
  timer.lap("density");

  const FloorPlane& plane = floor_.plane;
  r.to_output = config_.align_to_floor ? alignToFloor(plane) : Eigen::Isometry3d::Identity();
  std::vector<Eigen::Vector3d> cams_in;
  for (const auto& c : cameras)
  {
    if (c.allFinite())
    {
      cams_in.push_back(c);
    }
  }
  if (cams_in.empty())
  {
    cams_in.push_back(Eigen::Vector3d::Zero());
  }
  std::vector<double> cam_height(cams_in.size());
  for (std::size_t c = 0; c < cams_in.size(); ++c)
  {
    r.cameras.push_back(r.to_output * cams_in[c]);
    cam_height[c] = plane.normal.dot(cams_in[c]) + plane.d;
  }
  const PointList out = config_.align_to_floor ? transformPoints(points, r.to_output) : points;
  std::vector<std::size_t> nearest(points.size(), 0);
  if (cams_in.size() > 1)
  {
    for (std::size_t i = 0; i < points.size(); ++i)
    {
      const Eigen::Vector3d p = points[i].cast<double>();
      double best = std::numeric_limits<double>::infinity();
      for (std::size_t c = 0; c < cams_in.size(); ++c)
      {
        const double d = (p - cams_in[c]).squaredNorm();
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
    r.octree = octree_->insert(out, r.cameras, nearest);
    timer.lap("octree");
  }

  const double z_lo = config_.floor_clearance_m, z_hi = config_.ceiling_height_m;
  const bool filter = octree_ && config_.free_space_filter;
  // Heights first, so that the octree states of the band points come from one batch query.
  std::vector<double> heights(points.size());
  PointList band;
  for (std::size_t i = 0; i < points.size(); ++i)
  {
    heights[i] = plane.normal.dot(points[i].cast<double>()) + plane.d;
    if (filter && !(heights[i] < z_lo) && !(heights[i] > z_hi))
    {
      band.push_back(out[i]);
    }
  }
  const std::vector<VoxelState> band_states = filter ? octree_->query(band) : std::vector<VoxelState>();
  std::size_t next_band = 0;
  r.obstacles.reserve(points.size());
  r.rays.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
  {
    const double h = heights[i];
    if (h < z_lo)
    {
      ++r.n_floor_band;
      if (h > -z_lo)
      {
        r.floor_points.push_back(out[i]);
      }
    }
    else if (h > z_hi)
    {
      ++r.n_ceiling_band;
    }
    else if (filter && band_states[next_band++] == VoxelState::kFree)
    {
      ++r.n_freed;
    }
    else
    {
      r.obstacles.push_back(out[i]);
    }
    // The part of the ray from the nearest camera that lies inside the band, in heights.
    const double hc = cam_height[nearest[i]];
    const double dh = h - hc;
    double t0 = 0.0, t1 = 1.0;
    if (std::abs(dh) < 1e-12)
    {
      if (hc < z_lo || hc > z_hi)
      {
        continue;
      }
    }
    else
    {
      double ta = (z_lo - hc) / dh, tb = (z_hi - hc) / dh;
      if (ta > tb)
      {
        std::swap(ta, tb);
      }
      t0 = std::max(t0, ta);
      t1 = std::min(t1, tb);
      if (t0 > t1)
      {
        continue;
      }
    }
    const Eigen::Vector3d& c = r.cameras[nearest[i]];
    const Eigen::Vector3d p = out[i].cast<double>();
    r.rays.push_back(FreeRay{ (c + t0 * (p - c)).head<2>(), (c + t1 * (p - c)).head<2>() });
  }
  timer.lap("slice");
  r.ok = true;
  char buf[256];
  std::snprintf(buf, sizeof(buf), "%zu points: %zu floor band, %zu ceiling band, %zu obstacles, %zu in free space; "
                "floor tilt %.1f deg",
                points.size(), r.n_floor_band, r.n_ceiling_band, r.obstacles.size(), r.n_freed, plane.tilt_deg);
  r.status = buf;
  return r;
}

}  // namespace sparse_nav
