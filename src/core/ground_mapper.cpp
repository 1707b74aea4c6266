#include "sparse_nav/core/ground_mapper.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "radix_sort.h"

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

/// The part of the ray from a camera (position c, height hc above the floor) to point p (height h)
/// that lies between the heights z_lo and z_hi, projected to x-y; false when none does.
bool bandRay(const Eigen::Vector3d& c, double hc, const Eigen::Vector3f& p, double h, double z_lo, double z_hi,
             FreeRay& ray)
{
  const double dh = h - hc;
  double t0 = 0.0, t1 = 1.0;
  if (std::abs(dh) < 1e-12)
  {
    if (hc < z_lo || hc > z_hi)
    {
      return false;
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
      return false;
    }
  }
  const Eigen::Vector3d q = p.cast<double>();
  ray = FreeRay{ (c + t0 * (q - c)).head<2>(), (c + t1 * (q - c)).head<2>() };
  return true;
}
}  // namespace

void GroundMapperConfig::validate() const
{
  if (!std::isfinite(floor_clearance_m) || !std::isfinite(ceiling_height_m) || !(ceiling_height_m > floor_clearance_m))
  {
    throw std::invalid_argument("GroundMapperConfig: ceiling_height_m must be finite and above floor_clearance_m");
  }
  if (clear_hit_min_rays < 0 || !(clear_cell_m > 0.0) || !std::isfinite(clear_cell_m) ||
      !(clear_height_tolerance_m >= 0.0) || !std::isfinite(clear_height_tolerance_m) ||
      !(clear_range_margin >= 0.0 && clear_range_margin < 1.0))
  {
    throw std::invalid_argument("GroundMapperConfig: clear_hit_min_rays must be >= 0, clear_cell_m > 0, "
                                "clear_height_tolerance_m >= 0 and clear_range_margin in [0, 1)");
  }
  floor.validate();
  density.validate();
  octree.validate();
}

GroundMapper::GroundMapper(const GroundMapperConfig& config)
  : config_((config.validate(), config))
  , detector_(config.floor)
  , density_(config.density)
  , pass_count_(RayPassConfig{ config.clear_cell_m, config.clear_height_tolerance_m, config.clear_range_margin,
                               config.clear_max_cells })
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
  last_input_.clear();
  last_keep_.clear();
  last_dense_of_input_.clear();
  last_kind_.clear();
  if (octree_)
  {
    octree_->clear();
  }
}

std::vector<FreeRay> GroundMapper::rays() const
{
  std::vector<FreeRay> rays;
  if (last_kind_.empty())
  {
    return rays;
  }
  rays.reserve(last_out_.size());
  FreeRay ray;
  for (std::size_t k = 0; k < last_out_.size(); ++k)
  {
    if (bandRay(last_cameras_out_[last_camera_[k]], last_camera_h_[last_camera_[k]], last_out_[k], last_h_[k],
                config_.floor_clearance_m, config_.ceiling_height_m, ray))
    {
      rays.push_back(ray);
    }
  }
  return rays;
}

GroundMapperResult GroundMapper::process(const PointList& input, const std::vector<Eigen::Vector3d>& cameras,
                                         const std::vector<std::int32_t>* previous_index)
{
  GroundMapperResult r;
  StageTimer timer(r.stages_ms);
  bool floor_moved = !has_floor_;
  if (!has_floor_ || !config_.keep_floor)
  {
    const FloorResult found = detector_.detect(input);
    if (found.found)
    {
      const bool moved = has_floor_ && (found.plane.normal != floor_.plane.normal || found.plane.d != floor_.plane.d);
      floor_moved = floor_moved || moved;
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
      last_input_ = input;
      last_keep_.clear();
      last_dense_of_input_.clear();
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
  const bool has_previous = previous_index && previous_index->size() == input.size() && !last_keep_.empty();
  std::vector<char> keep = has_previous
                               ? density_.keepFlagsUpdated(input, *previous_index, last_input_, last_keep_, &r.density)
                               : density_.keepFlags(input, &r.density);
  // The points that go on (by their index in input), and for each the index it had among those of
  // the last call (-1: new). Scratch members here and below keep their capacity between calls:
  // fresh buffers per update cost more in page faults than the update's own work.
  std::vector<std::uint32_t>& kept = kept_;
  kept.clear();
  std::vector<std::int32_t>& dense_of_input = dense_of_input_;
  dense_of_input.assign(input.size(), -1);
  std::vector<std::int32_t>& dense_previous = dense_previous_;
  dense_previous.clear();
  for (std::size_t i = 0; i < input.size(); ++i)
  {
    if (keep[i])
    {
      dense_of_input[i] = static_cast<std::int32_t>(kept.size());
      kept.push_back(static_cast<std::uint32_t>(i));
      if (has_previous)  // read only when this call continues from the last
      {
        const std::int32_t k = (*previous_index)[i];
        dense_previous.push_back(k >= 0 && static_cast<std::size_t>(k) < last_dense_of_input_.size()
                                     ? last_dense_of_input_[static_cast<std::size_t>(k)]
                                     : -1);
      }
    }
  }
  last_input_ = input;
  last_keep_ = std::move(keep);
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
  // The same points under the same floor and cameras keep their camera, their band and their
  // octree state (the octree only adds hits in voxels it has not seen and frees none that holds
  // a point of the cloud), so only the new points are looked at and the ray count changes by them.
  const bool continues = has_previous && !floor_moved && cams_in == last_cameras_ && !last_kind_.empty();
  // The index of point i among the last call's points when this call continues from it, else -1.
  auto previousOf = [&](std::size_t i) { return continues ? dense_previous[i] : std::int32_t{ -1 }; };
  std::vector<double> cam_height(cams_in.size());
  for (std::size_t c = 0; c < cams_in.size(); ++c)
  {
    r.cameras.push_back(r.to_output * cams_in[c]);
    cam_height[c] = plane.normal.dot(cams_in[c]) + plane.d;
  }
  // In the output frame, as transformPoints() maps them.
  const std::size_t n_points = kept.size();
  auto pointAt = [&](std::size_t i) -> const Eigen::Vector3f& { return input[kept[i]]; };
  PointList& out = out_;
  out.resize(n_points);
  const Eigen::Isometry3f to_output = r.to_output.cast<float>();
  for (std::size_t i = 0; i < n_points; ++i)
  {
    if (config_.align_to_floor)
    {
      out[i] = to_output * pointAt(i);
    }
    else
    {
      out[i] = pointAt(i);
    }
  }
  std::vector<std::size_t>& nearest = nearest_;
  nearest.assign(n_points, 0);
  if (cams_in.size() > 1)
  {
    for (std::size_t i = 0; i < n_points; ++i)
    {
      if (previousOf(i) >= 0)
      {
        nearest[i] = last_camera_[static_cast<std::size_t>(previousOf(i))];
        continue;
      }
      const Eigen::Vector3d p = pointAt(i).cast<double>();
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

  if (octree_ && continues)
  {
    // Only the new points can cast rays or hit voxels; all keep their voxels from being freed.
    PointList fresh;
    std::vector<std::size_t> fresh_nearest;
    for (std::size_t i = 0; i < n_points; ++i)
    {
      if (previousOf(i) < 0)
      {
        fresh.push_back(out[i]);
        fresh_nearest.push_back(nearest[i]);
      }
    }
    r.octree = octree_->insert(fresh, r.cameras, fresh_nearest, &out);
    timer.lap("octree");
  }
  else if (octree_)
  {
    r.octree = octree_->insert(out, r.cameras, nearest);
    timer.lap("octree");
  }

  const double z_lo = config_.floor_clearance_m, z_hi = config_.ceiling_height_m;
  const bool filter = octree_ && config_.free_space_filter;
  // Heights first, so that the octree states of the band points come from one batch query.
  std::vector<double>& heights = heights_;
  heights.resize(n_points);
  std::vector<char>& kind = kind_;
  kind.resize(n_points);
  PointList band;
  std::vector<std::size_t> band_index;
  for (std::size_t i = 0; i < n_points; ++i)
  {
    if (previousOf(i) >= 0)
    {
      heights[i] = last_h_[static_cast<std::size_t>(previousOf(i))];
      kind[i] = last_kind_[static_cast<std::size_t>(previousOf(i))];
      continue;
    }
    heights[i] = plane.normal.dot(pointAt(i).cast<double>()) + plane.d;
    if (heights[i] < z_lo)
    {
      kind[i] = kFloorBand;
    }
    else if (heights[i] > z_hi)
    {
      kind[i] = kCeilingBand;
    }
    else
    {
      kind[i] = kCandidate;
      if (filter)
      {
        band.push_back(out[i]);
        band_index.push_back(i);
      }
    }
  }
  if (filter)
  {
    const std::vector<VoxelState> band_states = octree_->query(band);
    for (std::size_t j = 0; j < band.size(); ++j)
    {
      if (band_states[j] == VoxelState::kFree)
      {
        kind[band_index[j]] = kFreed;
      }
    }
  }
  // Scratch kept between calls: its pages are reused rather than faulted in again.
  std::vector<PassCandidate>& candidates = candidates_;
  std::vector<std::size_t>& candidate_index = candidate_index_;
  candidates.clear();
  candidate_index.clear();
  r.obstacles.reserve(n_points);
  if (!continues)
  {
    r.rays.reserve(n_points);
  }
  FreeRay ray;
  for (std::size_t i = 0; i < n_points; ++i)
  {
    const double h = heights[i];
    switch (kind[i])
    {
      case kFloorBand:
        ++r.n_floor_band;
        if (h > -z_lo)
        {
          r.floor_points.push_back(out[i]);
        }
        break;
      case kCeilingBand:
        ++r.n_ceiling_band;
        break;
      case kFreed:
        ++r.n_freed;
        break;
      default:
        candidates.push_back(PassCandidate{ out[i].head<2>().cast<double>(), h });
        candidate_index.push_back(i);
    }
    if (!continues && bandRay(r.cameras[nearest[i]], cam_height[nearest[i]], out[i], h, z_lo, z_hi, ray))
    {
      r.rays.push_back(ray);
    }
  }
  timer.lap("slice");

  // The last call's points that no point of this one took over.
  std::vector<std::size_t> gone;
  if (continues)
  {
    std::vector<char> taken(last_kind_.size(), 0);
    for (const std::int32_t k : dense_previous)
    {
      if (k >= 0)
      {
        taken[static_cast<std::size_t>(k)] = 1;
      }
    }
    for (std::size_t k = 0; k < taken.size(); ++k)
    {
      if (!taken[k])
      {
        gone.push_back(k);
      }
    }
  }
  // Each point's ray from its camera, made when asked for rather than stored.
  auto rayOf = [&](std::size_t i) {
    return PassRay{ static_cast<std::uint32_t>(nearest[i]), out[i].head<2>().cast<double>(), heights[i] };
  };
  const PassRaySource all_rays{ n_points, rayOf };
  bool counted = true;
  if (config_.clear_hit_min_rays > 0)
  {
    std::vector<Eigen::Vector2d> cam_xy(r.cameras.size());
    for (std::size_t c = 0; c < r.cameras.size(); ++c)
    {
      cam_xy[c] = r.cameras[c].head<2>();
    }
    if (continues)
    {
      std::vector<PassRay> removed_rays, added_rays;
      std::vector<PassCandidate> removed_candidates, added_candidates;
      for (std::size_t i = 0; i < n_points; ++i)
      {
        if (previousOf(i) < 0)
        {
          added_rays.push_back(rayOf(i));
          if (kind[i] == kCandidate)
          {
            added_candidates.push_back(PassCandidate{ added_rays.back().end_xy, heights[i] });
          }
        }
      }
      for (const std::size_t k : gone)
      {
        const Eigen::Vector2d xy = last_out_[k].head<2>().cast<double>();
        removed_rays.push_back(PassRay{ static_cast<std::uint32_t>(last_camera_[k]), xy, last_h_[k] });
        if (last_kind_[k] == kCandidate)
        {
          removed_candidates.push_back(PassCandidate{ xy, last_h_[k] });
        }
      }
      counted = pass_count_.update(cam_xy, cam_height, removed_rays, added_rays, removed_candidates, added_candidates,
                                   all_rays, candidates);
    }
    else
    {
      counted = pass_count_.build(cam_xy, cam_height, all_rays, candidates);
    }
  }
  const std::uint32_t min_rays = static_cast<std::uint32_t>(config_.clear_hit_min_rays);
  std::vector<char>& obstacle = obstacle_;
  obstacle.assign(n_points, 0);
  for (std::size_t j = 0; j < candidates.size(); ++j)
  {
    if (config_.clear_hit_min_rays > 0 && counted && pass_count_.count(candidates[j].xy) >= min_rays)
    {
      ++r.n_passed;
    }
    else
    {
      obstacle[candidate_index[j]] = 1;
      r.obstacles.push_back(out[candidate_index[j]]);
    }
  }
  if (continues)
  {
    // How the obstacles and rays differ from the last call's, for an update of the grid by them alone.
    r.incremental = true;
    for (std::size_t i = 0; i < n_points; ++i)
    {
      const std::int32_t k = previousOf(i);
      if (k >= 0)
      {
        if (obstacle[i] != last_obstacle_[static_cast<std::size_t>(k)])
        {
          (obstacle[i] ? r.obstacles_added_xy : r.obstacles_removed_xy).push_back(out[i].head<2>().cast<double>());
        }
        continue;
      }
      if (obstacle[i])
      {
        r.obstacles_added_xy.push_back(out[i].head<2>().cast<double>());
      }
      if (bandRay(r.cameras[nearest[i]], cam_height[nearest[i]], out[i], heights[i], z_lo, z_hi, ray))
      {
        r.rays_added.push_back(ray);
      }
    }
    for (const std::size_t k : gone)
    {
      if (last_obstacle_[k])
      {
        r.obstacles_removed_xy.push_back(last_out_[k].head<2>().cast<double>());
      }
      if (bandRay(r.cameras[last_camera_[k]], cam_height[last_camera_[k]], last_out_[k], last_h_[k], z_lo, z_hi, ray))
      {
        r.rays_removed.push_back(ray);
      }
    }
  }
  // What the next call continues from.
  last_dense_of_input_.swap(dense_of_input_);
  last_cameras_ = cams_in;
  last_cameras_out_ = r.cameras;
  last_camera_h_ = cam_height;
  last_kind_.swap(kind_);
  last_obstacle_.swap(obstacle_);
  last_out_.swap(out_);
  last_h_.swap(heights_);
  last_camera_.swap(nearest_);
  timer.lap("clear");
  r.ok = true;
  char buf[320];
  std::snprintf(buf, sizeof(buf), "%zu points: %zu floor band, %zu ceiling band, %zu obstacles, %zu in free space, "
                "%zu seen past%s; floor tilt %.1f deg",
                n_points, r.n_floor_band, r.n_ceiling_band, r.obstacles.size(), r.n_freed, r.n_passed,
                counted ? "" : " (not counted: the cloud spans more than clear_max_cells)", plane.tilt_deg);
  r.status = buf;
  return r;
}

}  // namespace sparse_nav
