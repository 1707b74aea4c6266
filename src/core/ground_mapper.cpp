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

/// The candidates (indices into xy) whose cell at least min_rays rays pass through at their height.
/// Ray i runs from its camera (cam_xy, cam_h) to point i (xy, h); its own end cell does not count.
/// Returns false, marking nothing, when the candidates' cells span more than clear_max_cells.
bool passedThrough(const std::vector<Eigen::Vector2d>& xy, const std::vector<double>& h,
                   const std::vector<Eigen::Vector2d>& cam_xy, const std::vector<double>& cam_h,
                   const std::vector<std::size_t>& camera_of, const std::vector<std::size_t>& candidates,
                   const GroundMapperConfig& config, std::vector<char>& passed)
{
  passed.assign(candidates.size(), 0);
  if (candidates.empty())
  {
    return true;
  }
  const double cell = config.clear_cell_m;
  // Cell indices stay within +-2^26: differences of them fit 16.16 fixed point in 64 bits, and a
  // ray's end cell relative to the box, offset by 2^27, fits 32 bits per axis of a sort key.
  constexpr double kMaxCell = 67108864.0;
  constexpr int kCellOffset = 1 << 27;
  auto inReach = [&](const Eigen::Vector2d& p) {
    return p.allFinite() && std::abs(p.x() / cell) < kMaxCell && std::abs(p.y() / cell) < kMaxCell;
  };
  auto cellOf = [cell](const Eigen::Vector2d& p) {
    return Eigen::Vector2i(static_cast<int>(std::floor(p.x() / cell)), static_cast<int>(std::floor(p.y() / cell)));
  };
  Eigen::Array2d lo_m = xy[candidates.front()].array(), hi_m = lo_m;
  for (const std::size_t i : candidates)
  {
    lo_m = lo_m.min(xy[i].array());
    hi_m = hi_m.max(xy[i].array());
  }
  const Eigen::Array2d span = (hi_m - lo_m) / cell + 1.0;
  if (!inReach(lo_m.matrix()) || !inReach(hi_m.matrix()) ||
      !(span.x() * span.y() <= static_cast<double>(config.clear_max_cells)))
  {
    return false;
  }
  const Eigen::Vector2i lo = cellOf(lo_m.matrix()), hi = cellOf(hi_m.matrix());
  const Eigen::Vector2i size = hi - lo + Eigen::Vector2i::Ones();
  auto index = [&](const Eigen::Vector2i& c) {
    return static_cast<std::size_t>(c.y() - lo.y()) * size.x() + static_cast<std::size_t>(c.x() - lo.x());
  };
  // Per cell: from the tolerance below its lowest candidate up to its highest. Only rays under an
  // obstacle's top count against it: rays over a box, or over the near part of its top towards
  // the far part, do not say that it is not there.
  const double tol = config.clear_height_tolerance_m;
  const std::size_t n_cells = static_cast<std::size_t>(size.x()) * size.y();
  std::vector<float> z_lo(n_cells, std::numeric_limits<float>::infinity());
  std::vector<float> z_hi(n_cells, -std::numeric_limits<float>::infinity());
  for (const std::size_t i : candidates)
  {
    const std::size_t k = index(cellOf(xy[i]));
    z_lo[k] = std::min(z_lo[k], static_cast<float>(h[i] - tol));
    z_hi[k] = std::max(z_hi[k], static_cast<float>(h[i]));
  }
  // Blocks of kBlock x kBlock cells, one block of margin around the box: a block is hot when it or
  // a neighbour holds a candidate. The next kBlock cells of a ray stay within the 3 x 3 blocks
  // around its current cell, so a ray skips them whole from a cold block: rays spend most of
  // their length in open space, and walking every cell of 10^5 rays cost more than the octree.
  constexpr int kBlock = 8;  // the walk below divides by it with >> 3
  const int bw = (size.x() + kBlock - 1) / kBlock + 2, bh = (size.y() + kBlock - 1) / kBlock + 2;
  std::vector<char> has(static_cast<std::size_t>(bw) * bh, 0), hot(has.size(), 0);
  for (const std::size_t i : candidates)
  {
    const Eigen::Vector2i c = cellOf(xy[i]) - lo;
    has[static_cast<std::size_t>(c.y() / kBlock + 1) * bw + c.x() / kBlock + 1] = 1;
  }
  for (int by = 1; by < bh - 1; ++by)
  {
    for (int bx = 1; bx < bw - 1; ++bx)
    {
      if (has[static_cast<std::size_t>(by) * bw + bx])
      {
        for (int y = by - 1; y <= by + 1; ++y)
        {
          std::fill_n(hot.begin() + static_cast<std::ptrdiff_t>(y) * bw + bx - 1, 3, 1);
        }
      }
    }
  }
  // Rays from one camera to one end cell share their cells and differ only in height: walked once
  // as a group, whose heights sorted give the count at a cell by two binary searches (a wall's
  // cell holds points at many heights).
  struct RayEnd
  {
    std::uint64_t camera, cell;
    double h;
  };
  std::vector<RayEnd> ends;
  ends.reserve(xy.size());
  for (std::size_t i = 0; i < xy.size(); ++i)
  {
    if (inReach(cam_xy[camera_of[i]]) && inReach(xy[i]))
    {
      const Eigen::Vector2i e = cellOf(xy[i]) - lo + Eigen::Vector2i::Constant(kCellOffset);
      ends.push_back(RayEnd{ camera_of[i], static_cast<std::uint64_t>(e.x()) << 32 | static_cast<std::uint32_t>(e.y()), h[i] });
    }
  }
  radixSortBy(ends, [](const RayEnd& e) { return e.camera; });
  radixSortBy(ends, [](const RayEnd& e) { return e.cell; });
  std::vector<std::uint32_t> count(n_cells, 0);
  std::vector<double> heights;
  for (std::size_t g0 = 0, g1 = 0; g0 < ends.size(); g0 = g1)
  {
    heights.clear();
    for (g1 = g0; g1 < ends.size() && ends[g1].camera == ends[g0].camera && ends[g1].cell == ends[g0].cell; ++g1)
    {
      heights.push_back(ends[g1].h);
    }
    std::sort(heights.begin(), heights.end());
    const std::size_t c = ends[g0].camera;
    const Eigen::Vector2i a = cellOf(cam_xy[c]) - lo;
    const Eigen::Vector2i b(static_cast<int>(ends[g0].cell >> 32) - kCellOffset,
                            static_cast<int>(ends[g0].cell & 0xffffffffu) - kCellOffset);
    const int steps = std::max(std::abs(b.x() - a.x()), std::abs(b.y() - a.y()));
    if (steps == 0)
    {
      continue;
    }
    // A digital line in 16.16 fixed point, one cell per step along the major axis. Cells in the
    // last clear_range_margin of the ray may hold the same surface as its end; the end cell is its own.
    std::int64_t fx = (static_cast<std::int64_t>(a.x()) << 16) + (1 << 15);
    std::int64_t fy = (static_cast<std::int64_t>(a.y()) << 16) + (1 << 15);
    const std::int64_t dfx = (static_cast<std::int64_t>(b.x() - a.x()) << 16) / steps;
    const std::int64_t dfy = (static_cast<std::int64_t>(b.y() - a.y()) << 16) / steps;
    const double h0 = cam_h[c];
    const int last = std::min(steps - 1, static_cast<int>(std::floor((1.0 - config.clear_range_margin) * steps)));
    for (int s = 0; s <= last;)
    {
      const int x = static_cast<int>(fx >> 16), y = static_cast<int>(fy >> 16);  // floors
      const int bx = (x >> 3) + 1, by = (y >> 3) + 1;
      if (bx < 0 || by < 0 || bx >= bw || by >= bh || !hot[static_cast<std::size_t>(by) * bw + bx])
      {
        s += kBlock;
        fx += kBlock * dfx;
        fy += kBlock * dfy;
        continue;
      }
      if (x >= 0 && y >= 0 && x < size.x() && y < size.y())
      {
        const std::size_t k = static_cast<std::size_t>(y) * size.x() + static_cast<std::size_t>(x);
        if (z_lo[k] <= z_hi[k])
        {
          // At fraction f of the way, a ray to height hp is at h0 + f (hp - h0): within the cell's
          // range for hp in [h0 + (z_lo - h0) / f, h0 + (z_hi - h0) / f].
          if (s == 0)
          {
            count[k] += (h0 >= z_lo[k] && h0 <= z_hi[k]) ? static_cast<std::uint32_t>(heights.size()) : 0;
          }
          else
          {
            const double f = static_cast<double>(s) / steps;
            const auto from = std::lower_bound(heights.begin(), heights.end(), h0 + (z_lo[k] - h0) / f);
            const auto to = std::upper_bound(from, heights.end(), h0 + (z_hi[k] - h0) / f);
            count[k] += static_cast<std::uint32_t>(to - from);
          }
        }
      }
      ++s;
      fx += dfx;
      fy += dfy;
    }
  }
  const std::uint32_t min_rays = static_cast<std::uint32_t>(config.clear_hit_min_rays);
  for (std::size_t j = 0; j < candidates.size(); ++j)
  {
    passed[j] = count[index(cellOf(xy[candidates[j]]))] >= min_rays ? 1 : 0;
  }
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
  last_input_.clear();
  last_keep_.clear();
  if (octree_)
  {
    octree_->clear();
  }
}

GroundMapperResult GroundMapper::process(const PointList& input, const std::vector<Eigen::Vector3d>& cameras,
                                         const std::vector<std::int32_t>* previous_index)
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
      last_input_ = input;
      last_keep_.clear();
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
  std::vector<char> keep = previous_index && !last_keep_.empty()
                               ? density_.keepFlagsUpdated(input, *previous_index, last_input_, last_keep_, &r.density)
                               : density_.keepFlags(input, &r.density);
  PointList points;
  points.reserve(r.density.n_out);
  for (std::size_t i = 0; i < input.size(); ++i)
  {
    if (keep[i])
    {
      points.push_back(input[i]);
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
  std::vector<std::size_t> candidates;  // band points not proven free by the octree
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
      candidates.push_back(i);
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

  std::vector<char> passed;
  bool counted = true;
  if (config_.clear_hit_min_rays > 0)
  {
    std::vector<Eigen::Vector2d> xy(points.size()), cam_xy(r.cameras.size());
    for (std::size_t i = 0; i < points.size(); ++i)
    {
      xy[i] = out[i].head<2>().cast<double>();
    }
    for (std::size_t c = 0; c < r.cameras.size(); ++c)
    {
      cam_xy[c] = r.cameras[c].head<2>();
    }
    counted = passedThrough(xy, heights, cam_xy, cam_height, nearest, candidates, config_, passed);
  }
  for (std::size_t j = 0; j < candidates.size(); ++j)
  {
    if (!passed.empty() && passed[j])
    {
      ++r.n_passed;
    }
    else
    {
      r.obstacles.push_back(out[candidates[j]]);
    }
  }
  timer.lap("clear");
  r.ok = true;
  char buf[320];
  std::snprintf(buf, sizeof(buf), "%zu points: %zu floor band, %zu ceiling band, %zu obstacles, %zu in free space, "
                "%zu seen past%s; floor tilt %.1f deg",
                points.size(), r.n_floor_band, r.n_ceiling_band, r.obstacles.size(), r.n_freed, r.n_passed,
                counted ? "" : " (not counted: the cloud spans more than clear_max_cells)", plane.tilt_deg);
  r.status = buf;
  return r;
}

}  // namespace sparse_nav
