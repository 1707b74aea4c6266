#include "sparse_nav/core/ray_pass_count.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "radix_sort.h"

namespace sparse_nav
{
namespace
{
// Blocks of kBlock x kBlock cells, one block of margin around the box: a block is hot when it or
// a neighbour holds a candidate. The next kBlock cells of a ray stay within the 3 x 3 blocks
// around its current cell, so a ray skips them whole from a cold block: rays spend most of their
// length in open space.
constexpr int kBlock = 8;  // the walk divides by it with >> 3
constexpr double kKeyScale = 1073741824.0;  // pseudo-angles in [0, 4) to 32-bit keys

/// A monotone stand-in for atan2(y, x) in [0, 4): cheap, and sorting by it sorts by direction.
double pseudoAngle(double x, double y)
{
  const double sum = std::abs(x) + std::abs(y);
  if (sum == 0.0)
  {
    return 0.0;
  }
  const double p = y / sum;
  return x >= 0.0 ? (y >= 0.0 ? p : 4.0 + p) : 2.0 - p;
}

std::uint32_t angleKey(double pseudo)
{
  return static_cast<std::uint32_t>(std::min(std::max(pseudo * kKeyScale, 0.0), 4294967295.0));
}
}  // namespace

RayPassCount::RayPassCount(const RayPassConfig& config) : config_(config)
{
}

bool RayPassCount::counts(const PassRay& r) const
{
  return r.camera < camera_ok_.size() && camera_ok_[r.camera] && inReach(r.end_xy);
}

void RayPassCount::widen(std::size_t k, double h)
{
  if (slot_[k] == kNoCell)
  {
    slot_[k] = static_cast<std::uint32_t>(cells_.size());
    cells_.push_back(CandidateCell{ std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(), 0 });
  }
  CandidateCell& c = cells_[slot_[k]];
  c.z_lo = std::min(c.z_lo, static_cast<float>(h - config_.height_tolerance_m));
  c.z_hi = std::max(c.z_hi, static_cast<float>(h));
}

bool RayPassCount::inCameraCell(std::uint32_t camera, const IndexedRay& e) const
{
  return e.bx == camera_cell_[camera].x() && e.by == camera_cell_[camera].y();
}

std::size_t RayPassCount::blockOf(std::size_t k) const
{
  const std::size_t w = static_cast<std::size_t>(size_.x());
  return (k / w / kBlock + 1) * static_cast<std::size_t>(bw_) + (k % w) / kBlock + 1;
}

void RayPassCount::setHot()
{
  hot_.assign(block_cells_.size(), 0);
  for (int by = 1; by < bh_ - 1; ++by)
  {
    for (int bx = 1; bx < bw_ - 1; ++bx)
    {
      if (block_cells_[static_cast<std::size_t>(by) * bw_ + bx] > 0)
      {
        for (int y = by - 1; y <= by + 1; ++y)
        {
          std::fill_n(hot_.begin() + static_cast<std::ptrdiff_t>(y) * bw_ + bx - 1, 3, 1);
        }
      }
    }
  }
}

void RayPassCount::walk(std::size_t c, const Eigen::Vector2i& b_abs, const std::vector<double>& heights, int sign)
{
  const Eigen::Vector2i a = camera_cell_[c] - lo_;
  const Eigen::Vector2i b = b_abs - lo_;
  const int steps = std::max(std::abs(b.x() - a.x()), std::abs(b.y() - a.y()));
  if (steps == 0)
  {
    return;
  }
  // A digital line in 16.16 fixed point, one cell per step along the major axis. Cells in the
  // last range_margin of the ray may hold the same surface as its end; the end cell is its own.
  std::int64_t fx = static_cast<std::int64_t>(a.x()) * 65536 + 32768;
  std::int64_t fy = static_cast<std::int64_t>(a.y()) * 65536 + 32768;
  const std::int64_t dfx = static_cast<std::int64_t>(b.x() - a.x()) * 65536 / steps;
  const std::int64_t dfy = static_cast<std::int64_t>(b.y() - a.y()) * 65536 / steps;
  const double h0 = camera_h_[c];
  const int last = std::min(steps - 1, static_cast<int>(std::floor((1.0 - config_.range_margin) * steps)));
  for (int s = 0; s <= last;)
  {
    const int x = static_cast<int>(fx >> 16), y = static_cast<int>(fy >> 16);  // floors
    const int bx = (x >> 3) + 1, by = (y >> 3) + 1;
    if (bx < 0 || by < 0 || bx >= bw_ || by >= bh_ || !hot_[static_cast<std::size_t>(by) * bw_ + bx])
    {
      s += kBlock;
      fx += kBlock * dfx;
      fy += kBlock * dfy;
      continue;
    }
    if (x >= 0 && y >= 0 && x < size_.x() && y < size_.y())
    {
      CandidateCell* cell = candidateCell(static_cast<std::size_t>(y) * size_.x() + static_cast<std::size_t>(x));
      if (cell && cell->z_lo <= cell->z_hi)
      {
        // At fraction f of the way, a ray to height hp is at h0 + f (hp - h0): within the cell's
        // range for hp in [h0 + (z_lo - h0) / f, h0 + (z_hi - h0) / f].
        std::uint32_t n = 0;
        if (s == 0)
        {
          n = (h0 >= cell->z_lo && h0 <= cell->z_hi) ? static_cast<std::uint32_t>(heights.size()) : 0;
        }
        else
        {
          const double f = static_cast<double>(s) / steps;
          const auto from = std::lower_bound(heights.begin(), heights.end(), h0 + (cell->z_lo - h0) / f);
          const auto to = std::upper_bound(from, heights.end(), h0 + (cell->z_hi - h0) / f);
          n = static_cast<std::uint32_t>(to - from);
        }
        cell->count += sign > 0 ? n : static_cast<std::uint32_t>(0) - n;
      }
    }
    ++s;
    fx += dfx;
    fy += dfy;
  }
}

bool RayPassCount::visits(const Eigen::Vector2i& a, const Eigen::Vector2i& b, const Eigen::Vector2i& k, int& s) const
{
  // The walk's line, taken at the one step where its major coordinate is k's; offsets cancel
  // in the fixed point, so absolute cells give the walk's cells.
  const Eigen::Vector2i d = b - a;
  const int steps = std::max(std::abs(d.x()), std::abs(d.y()));
  if (steps == 0)
  {
    return false;
  }
  const int last = std::min(steps - 1, static_cast<int>(std::floor((1.0 - config_.range_margin) * steps)));
  const bool major_x = std::abs(d.x()) == steps;
  const int major = major_x ? 0 : 1, minor = 1 - major;
  s = (k[major] - a[major]) * (d[major] > 0 ? 1 : -1);
  if (s < 0 || s > last)
  {
    return false;
  }
  const std::int64_t df = static_cast<std::int64_t>(d[minor]) * 65536 / steps;
  const std::int64_t f = 32768 + static_cast<std::int64_t>(s) * df;
  return a[minor] + static_cast<int>(f >> 16) == k[minor];
}

std::uint32_t RayPassCount::recount(const Eigen::Vector2i& k) const
{
  const CandidateCell* cell = candidateCell(index(k));
  if (!cell || !(cell->z_lo <= cell->z_hi))
  {
    return 0;
  }
  const float zl = cell->z_lo, zh = cell->z_hi;
  std::uint32_t total = 0;
  auto tally = [&](std::size_t c, const IndexedRay& e) {
    int s = 0;
    if (e.deleted || !visits(camera_cell_[c], Eigen::Vector2i(e.bx, e.by), k, s))
    {
      return;
    }
    const double h0 = camera_h_[c];
    if (s == 0)
    {
      total += (h0 >= zl && h0 <= zh) ? 1 : 0;
      return;
    }
    const int steps = std::max(std::abs(e.bx - camera_cell_[c].x()), std::abs(e.by - camera_cell_[c].y()));
    const double f = static_cast<double>(s) / steps;
    total += (e.h >= h0 + (zl - h0) / f && e.h <= h0 + (zh - h0) / f) ? 1 : 0;
  };
  for (std::size_t c = 0; c < index_.size(); ++c)
  {
    const CameraIndex& ci = index_[c];
    const Eigen::Vector2d v = (k - camera_cell_[c]).cast<double>();
    const double dist = v.norm();
    // A ray visiting k passes within half a cell of its centre, plus the fixed point's rounding
    // (under 1 / 65536 cell per step): one and a half cells leaves a margin.
    const double reach = 1.5 + dist / 65536.0;
    auto scanBoth = [&](std::uint32_t from, std::uint32_t to) {
      for (std::uint32_t b = from >> kBucketShift; b <= (to >> kBucketShift); ++b)
      {
        for (std::uint32_t e = ci.start[b]; e < ci.start[b + 1]; ++e)
        {
          if (ci.rays[e].key >= from && ci.rays[e].key <= to)
          {
            tally(c, ci.rays[e]);
          }
        }
      }
      auto it = std::lower_bound(ci.added.begin(), ci.added.end(), from,
                                 [](const IndexedRay& e, std::uint32_t key) { return e.key < key; });
      for (; it != ci.added.end() && it->key <= to; ++it)
      {
        tally(c, *it);
      }
    };
    if (dist <= reach)
    {
      scanBoth(0, std::numeric_limits<std::uint32_t>::max());
      continue;
    }
    const double delta = std::asin(reach / dist);
    const double cd = std::cos(delta), sd = std::sin(delta);
    const double p1 = pseudoAngle(v.x() * cd + v.y() * sd, -v.x() * sd + v.y() * cd);
    const double p2 = pseudoAngle(v.x() * cd - v.y() * sd, v.x() * sd + v.y() * cd);
    const std::uint32_t k1 = angleKey(p1) > 0 ? angleKey(p1) - 1 : 0;
    const std::uint32_t k2 = angleKey(p2) < std::numeric_limits<std::uint32_t>::max() ? angleKey(p2) + 1 : angleKey(p2);
    if (p1 <= p2)
    {
      scanBoth(k1, k2);
    }
    else
    {
      scanBoth(k1, std::numeric_limits<std::uint32_t>::max());
      scanBoth(0, k2);
    }
  }
  return total;
}

RayPassCount::IndexedRay RayPassCount::indexed(const PassRay& ray) const
{
  const Eigen::Vector2i b = cellOf(ray.end_xy);
  const Eigen::Vector2i d = b - camera_cell_[ray.camera];
  return IndexedRay{ ray.end_h, angleKey(pseudoAngle(d.x(), d.y())), b.x(), b.y(), false };
}

std::vector<RayPassCount::End> RayPassCount::sortedEnds(const PassRaySource& rays) const
{
  std::vector<End> ends;
  ends.reserve(rays.size);
  for (std::size_t i = 0; i < rays.size; ++i)
  {
    const PassRay r = rays.at(i);
    if (counts(r))
    {
      const Eigen::Vector2i e = cellOf(r.end_xy) + Eigen::Vector2i::Constant(kCellOffset);
      ends.push_back(End{ r.camera, static_cast<std::uint64_t>(e.x()) << 32 | static_cast<std::uint32_t>(e.y()), r.end_h });
    }
  }
  radixSortBy(ends, [](const End& e) { return e.camera; });
  radixSortBy(ends, [](const End& e) { return e.cell; });
  return ends;
}

Eigen::Vector2i RayPassCount::endCell(const End& e)
{
  return Eigen::Vector2i(static_cast<int>(e.cell >> 32) - kCellOffset, static_cast<int>(e.cell & 0xffffffffu) - kCellOffset);
}

void RayPassCount::indexRays(const std::vector<End>& ends)
{
  // Bucketed by direction in two passes (count, place): cheaper than sorting, and a window of
  // directions is a run of buckets. A run of ends shares its direction, taken once.
  constexpr std::size_t kBuckets = std::size_t{ 1 } << (32 - kBucketShift);
  auto forEachRun = [&](auto visit) {
    for (std::size_t g0 = 0, g1 = 0; g0 < ends.size(); g0 = g1)
    {
      for (g1 = g0 + 1; g1 < ends.size() && ends[g1].camera == ends[g0].camera && ends[g1].cell == ends[g0].cell; ++g1)
      {
      }
      const std::size_t camera = static_cast<std::size_t>(ends[g0].camera);
      const Eigen::Vector2i b = endCell(ends[g0]);
      const Eigen::Vector2i d = b - camera_cell_[camera];
      if (d.x() != 0 || d.y() != 0)  // a ray that ends in its camera's cell passes nothing and is not indexed
      {
        visit(index_[camera], angleKey(pseudoAngle(d.x(), d.y())), b, g0, g1);
      }
    }
  };
  index_.assign(camera_xy_.size(), CameraIndex());
  for (auto& ci : index_)
  {
    ci.start.assign(kBuckets + 1, 0);
  }
  forEachRun([](CameraIndex& ci, std::uint32_t key, const Eigen::Vector2i&, std::size_t g0, std::size_t g1) {
    ci.start[(key >> kBucketShift) + 1] += static_cast<std::uint32_t>(g1 - g0);
  });
  std::vector<std::vector<std::uint32_t>> fill(index_.size());
  for (std::size_t c = 0; c < index_.size(); ++c)
  {
    CameraIndex& ci = index_[c];
    for (std::size_t b = 1; b <= kBuckets; ++b)
    {
      ci.start[b] += ci.start[b - 1];
    }
    ci.rays.resize(ci.start[kBuckets]);
    fill[c].assign(ci.start.begin(), ci.start.end() - 1);
  }
  forEachRun([&](CameraIndex& ci, std::uint32_t key, const Eigen::Vector2i& b, std::size_t g0, std::size_t g1) {
    std::uint32_t& at = fill[static_cast<std::size_t>(&ci - index_.data())][key >> kBucketShift];
    for (std::size_t g = g0; g < g1; ++g)
    {
      ci.rays[at++] = IndexedRay{ ends[g].h, key, b.x(), b.y(), false };
    }
  });
}

bool RayPassCount::build(const std::vector<Eigen::Vector2d>& camera_xy, const std::vector<double>& camera_h,
                         const PassRaySource& rays, const std::vector<PassCandidate>& candidates)
{
  last_was_build_ = true;
  n_recounted_ = 0;
  counted_ = false;
  camera_xy_ = camera_xy;
  camera_h_ = camera_h;
  camera_cell_.assign(camera_xy.size(), Eigen::Vector2i::Zero());
  camera_ok_.assign(camera_xy.size(), 0);
  for (std::size_t c = 0; c < camera_xy.size(); ++c)
  {
    camera_ok_[c] = inReach(camera_xy[c]) ? 1 : 0;
    if (camera_ok_[c])
    {
      camera_cell_[c] = cellOf(camera_xy[c]);
    }
  }
  size_ = Eigen::Vector2i::Zero();
  slot_.clear();
  cells_.clear();
  block_cells_.clear();
  hot_.clear();
  index_.clear();
  bw_ = bh_ = 0;
  if (candidates.empty())
  {
    counted_ = true;
    return true;
  }
  Eigen::Array2d lo_m = candidates.front().xy.array(), hi_m = lo_m;
  for (const auto& p : candidates)
  {
    lo_m = lo_m.min(p.xy.array());
    hi_m = hi_m.max(p.xy.array());
  }
  const Eigen::Array2d span = (hi_m - lo_m) / config_.cell_m + 1.0;
  if (!inReach(lo_m.matrix()) || !inReach(hi_m.matrix()) || !(span.x() * span.y() <= static_cast<double>(config_.max_cells)))
  {
    return false;
  }
  lo_ = cellOf(lo_m.matrix());
  size_ = cellOf(hi_m.matrix()) - lo_ + Eigen::Vector2i::Ones();
  const std::size_t n_cells = static_cast<std::size_t>(size_.x()) * static_cast<std::size_t>(size_.y());
  // Per cell: from the tolerance below its lowest candidate up to its highest. Only rays under an
  // obstacle's top count against it: rays over a box, or over the near part of its top towards
  // the far part, do not say that it is not there.
  slot_.assign(n_cells, kNoCell);
  for (const auto& p : candidates)
  {
    widen(index(cellOf(p.xy)), p.h);
  }
  bw_ = (size_.x() + kBlock - 1) / kBlock + 2;
  bh_ = (size_.y() + kBlock - 1) / kBlock + 2;
  block_cells_.assign(static_cast<std::size_t>(bw_) * bh_, 0);
  for (std::size_t k = 0; k < n_cells; ++k)
  {
    block_cells_[blockOf(k)] += holdsCandidates(k) ? 1 : 0;
  }
  setHot();
  // Rays from one camera to one end cell share their cells and differ only in height: walked once
  // as a group, whose heights sorted give the count at a cell by two binary searches (a wall's
  // cell holds points at many heights).
  const std::vector<End> ends = sortedEnds(rays);
  std::vector<double> heights;
  for (std::size_t g0 = 0, g1 = 0; g0 < ends.size(); g0 = g1)
  {
    heights.clear();
    for (g1 = g0; g1 < ends.size() && ends[g1].camera == ends[g0].camera && ends[g1].cell == ends[g0].cell; ++g1)
    {
      heights.push_back(ends[g1].h);
    }
    std::sort(heights.begin(), heights.end());
    walk(ends[g0].camera, endCell(ends[g0]), heights, +1);
  }
  indexRays(ends);
  counted_ = true;
  return true;
}

bool RayPassCount::update(const std::vector<Eigen::Vector2d>& camera_xy, const std::vector<double>& camera_h,
                          const std::vector<PassRay>& removed_rays, const std::vector<PassRay>& added_rays,
                          const std::vector<PassCandidate>& removed_candidates,
                          const std::vector<PassCandidate>& added_candidates, const PassRaySource& rays,
                          const std::vector<PassCandidate>& candidates)
{
  const bool same_cameras = camera_xy == camera_xy_ && camera_h == camera_h_;
  if (!counted_ || !same_cameras || size_.x() == 0)
  {
    return build(camera_xy, camera_h, rays, candidates);
  }
  for (const auto& p : added_candidates)
  {
    if (!inReach(p.xy) || !inBox(cellOf(p.xy)))
    {
      return build(camera_xy, camera_h, rays, candidates);
    }
  }
  last_was_build_ = false;
  // Cells whose candidates changed: their height range is taken again from every candidate, and
  // their count from nothing after the rays below.
  std::vector<std::size_t> changed;
  std::vector<char> is_changed(slot_.size(), 0);
  auto markChanged = [&](const PassCandidate& p) {
    const Eigen::Vector2i c = cellOf(p.xy);
    if (inReach(p.xy) && inBox(c) && !is_changed[index(c)])
    {
      is_changed[index(c)] = 1;
      changed.push_back(index(c));
    }
  };
  for (const auto& p : removed_candidates)
  {
    markChanged(p);
  }
  for (const auto& p : added_candidates)
  {
    markChanged(p);
  }
  for (const std::size_t k : changed)
  {
    block_cells_[blockOf(k)] -= holdsCandidates(k) ? 1 : 0;
    if (CandidateCell* cell = candidateCell(k))
    {
      cell->z_lo = std::numeric_limits<float>::infinity();
      cell->z_hi = -std::numeric_limits<float>::infinity();
    }
  }
  if (!changed.empty())
  {
    // The changed cells' box in metres, a cell wider: most candidates fail it before their cell is taken.
    Eigen::Array2d lo_m(std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()), hi_m = -lo_m;
    for (const std::size_t k : changed)
    {
      const Eigen::Array2d c(lo_.x() + static_cast<double>(k % size_.x()), lo_.y() + static_cast<double>(k / size_.x()));
      lo_m = lo_m.min((c - 1.0) * config_.cell_m);
      hi_m = hi_m.max((c + 2.0) * config_.cell_m);
    }
    for (const auto& p : candidates)
    {
      if ((p.xy.array() < lo_m).any() || (p.xy.array() > hi_m).any())
      {
        continue;
      }
      const Eigen::Vector2i c = cellOf(p.xy);
      if (!inBox(c) || !is_changed[index(c)])
      {
        continue;
      }
      widen(index(c), p.h);
    }
  }
  for (const std::size_t k : changed)
  {
    block_cells_[blockOf(k)] += holdsCandidates(k) ? 1 : 0;
  }
  setHot();

  std::vector<double> one(1);
  for (const auto& r : removed_rays)
  {
    if (!counts(r))
    {
      continue;
    }
    const IndexedRay e = indexed(r);
    CameraIndex& ci = index_[r.camera];
    bool found = false;
    auto same = [&](const IndexedRay& x) { return !x.deleted && x.bx == e.bx && x.by == e.by && x.h == e.h; };
    auto first = [&](std::vector<IndexedRay>& v) {
      return std::lower_bound(v.begin(), v.end(), e.key, [](const IndexedRay& x, std::uint32_t key) { return x.key < key; });
    };
    for (auto it = first(ci.added); !found && it != ci.added.end() && it->key == e.key; ++it)
    {
      if (same(*it))
      {
        ci.added.erase(it);
        found = true;
        break;
      }
    }
    const std::uint32_t bucket = e.key >> kBucketShift;
    for (std::uint32_t k = ci.start[bucket]; !found && k < ci.start[bucket + 1]; ++k)
    {
      if (ci.rays[k].key == e.key && same(ci.rays[k]))
      {
        ci.rays[k].deleted = true;
        ++ci.n_deleted;
        found = true;
      }
    }
    if (inCameraCell(r.camera, e))
    {
      continue;  // a ray that ends in its camera's cell passes nothing and is not indexed
    }
    if (!found)
    {
      return build(camera_xy, camera_h, rays, candidates);  // a ray never added: start again
    }
    one[0] = r.end_h;
    walk(r.camera, Eigen::Vector2i(e.bx, e.by), one, -1);
  }
  std::vector<std::vector<IndexedRay>> fresh(index_.size());
  for (const auto& r : added_rays)
  {
    if (!counts(r))
    {
      continue;
    }
    const IndexedRay e = indexed(r);
    if (inCameraCell(r.camera, e))
    {
      continue;
    }
    one[0] = r.end_h;
    walk(r.camera, Eigen::Vector2i(e.bx, e.by), one, +1);
    fresh[r.camera].push_back(e);
  }
  std::size_t n_indexed = 0, n_stale = 0;
  for (std::size_t c = 0; c < index_.size(); ++c)
  {
    CameraIndex& ci = index_[c];
    if (!fresh[c].empty())
    {
      std::sort(fresh[c].begin(), fresh[c].end(), [](const IndexedRay& a, const IndexedRay& b) { return a.key < b.key; });
      const std::size_t middle = ci.added.size();
      ci.added.insert(ci.added.end(), fresh[c].begin(), fresh[c].end());
      std::inplace_merge(ci.added.begin(), ci.added.begin() + static_cast<std::ptrdiff_t>(middle), ci.added.end(),
                         [](const IndexedRay& a, const IndexedRay& b) { return a.key < b.key; });
    }
    n_indexed += ci.rays.size();
    n_stale += ci.added.size() + ci.n_deleted;
  }
  n_recounted_ = changed.size();
  for (const std::size_t k : changed)
  {
    if (CandidateCell* cell = candidateCell(k))  // a cell that never held candidates counts nothing
    {
      cell->count = recount(Eigen::Vector2i(lo_.x() + static_cast<int>(k % size_.x()), lo_.y() + static_cast<int>(k / size_.x())));
    }
  }
  // The rays added since the index was made are scanned in a second list, and the deleted ones
  // skipped: once they are a quarter of it, the index is made again.
  if (4 * n_stale > n_indexed)
  {
    indexRays(sortedEnds(rays));
  }
  return true;
}

std::uint32_t RayPassCount::count(const Eigen::Vector2d& xy) const
{
  if (!counted_ || size_.x() == 0 || !inReach(xy))
  {
    return 0;
  }
  const Eigen::Vector2i c = cellOf(xy);
  const CandidateCell* cell = inBox(c) ? candidateCell(index(c)) : nullptr;
  return cell ? cell->count : 0;
}

}  // namespace sparse_nav
