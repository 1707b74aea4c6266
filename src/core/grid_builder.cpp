#include "sparse_nav/core/grid_builder.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <stdexcept>
#include <tuple>
#include <utility>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "radix_sort.h"

namespace sparse_nav
{
namespace
{
std::int64_t floorDiv(std::int64_t a, std::int64_t b)
{
  std::int64_t q = a / b;
  if ((a % b != 0) && ((a < 0) != (b < 0)))
  {
    --q;
  }
  return q;
}

/// Integer Bresenham over every cell from (x0, y0) to (x1, y1), both included: max(|dx|, |dy|) + 1
/// cells. The steps are chosen without branches (a branch on them mispredicts along most lines).
template <typename Visit>
void bresenham(int x0, int y0, int x1, int y1, Visit visit)
{
  const int dx = std::abs(x1 - x0);
  const int dy = -std::abs(y1 - y0);
  const int sx = x0 < x1 ? 1 : -1;
  const int sy = y0 < y1 ? 1 : -1;
  int err = dx + dy;
  for (int n = std::max(dx, -dy); n >= 0; --n)
  {
    visit(x0, y0);
    const int e2 = 2 * err;
    const bool step_x = e2 >= dy;
    const bool step_y = e2 <= dx;
    err += (step_x ? dy : 0) + (step_y ? dx : 0);
    x0 += step_x ? sx : 0;
    y0 += step_y ? sy : 0;
  }
}

/// bresenham()'s walk as a cursor over the cells' indices row * width + col in a grid.
struct LineCursor
{
  int dx, dy, sx, sy, err, index, left;  // sy steps a row: +-width

  LineCursor(int x0, int y0, int x1, int y1, int width)
    : dx(std::abs(x1 - x0))
    , dy(-std::abs(y1 - y0))
    , sx(x0 < x1 ? 1 : -1)
    , sy(y0 < y1 ? width : -width)
    , err(dx + dy)
    , index(y0 * width + x0)
    , left(std::max(dx, -dy))
  {
  }
  void step()
  {
    const int e2 = 2 * err;
    const bool step_x = e2 >= dy;
    const bool step_y = e2 <= dx;
    err += (step_x ? dy : 0) + (step_y ? dx : 0);
    index += (step_x ? sx : 0) + (step_y ? sy : 0);
    --left;
  }
};

/// Adds 1 to cover[i] for the index i of each cell of each of n lines (line(k) gives the k-th
/// LineCursor). A line's steps wait each on the last (its error term), so one line at a time
/// leaves the core idle most of each step: with SSE2 four lines step at once, one per lane, and
/// each step's four cells are counted in turn; the last lines finish one at a time.
template <typename Line>
void coverLines(std::size_t n, Line line, std::uint32_t* cover)
{
  std::size_t next = 0;
#if defined(__SSE2__)
  if (n >= 4)
  {
    LineCursor lanes[4] = { line(0), line(1), line(2), line(3) };
    next = 4;
    alignas(16) int err[4], index[4], dx[4], dy[4], sx[4], sy[4];
    while (true)
    {
      int steps = lanes[0].left;
      for (int l = 0; l < 4; ++l)
      {
        err[l] = lanes[l].err;
        index[l] = lanes[l].index;
        dx[l] = lanes[l].dx;
        dy[l] = lanes[l].dy;
        sx[l] = lanes[l].sx;
        sy[l] = lanes[l].sy;
        steps = std::min(steps, lanes[l].left);
      }
      // Every lane takes steps + 1 cells: the one it is at and steps more.
      __m128i e = _mm_load_si128(reinterpret_cast<const __m128i*>(err));
      __m128i at = _mm_load_si128(reinterpret_cast<const __m128i*>(index));
      const __m128i vdx = _mm_load_si128(reinterpret_cast<const __m128i*>(dx));
      const __m128i vdy = _mm_load_si128(reinterpret_cast<const __m128i*>(dy));
      const __m128i vsx = _mm_load_si128(reinterpret_cast<const __m128i*>(sx));
      const __m128i vsy = _mm_load_si128(reinterpret_cast<const __m128i*>(sy));
      for (int s = 0; s <= steps; ++s)
      {
        alignas(16) int cells[4];
        _mm_store_si128(reinterpret_cast<__m128i*>(cells), at);
        ++cover[cells[0]];
        ++cover[cells[1]];
        ++cover[cells[2]];
        ++cover[cells[3]];
        const __m128i e2 = _mm_add_epi32(e, e);
        const __m128i step_x = _mm_xor_si128(_mm_cmpgt_epi32(vdy, e2), _mm_set1_epi32(-1));  // e2 >= dy
        const __m128i step_y = _mm_xor_si128(_mm_cmpgt_epi32(e2, vdx), _mm_set1_epi32(-1));  // e2 <= dx
        e = _mm_add_epi32(e, _mm_add_epi32(_mm_and_si128(step_x, vdy), _mm_and_si128(step_y, vdx)));
        at = _mm_add_epi32(at, _mm_add_epi32(_mm_and_si128(step_x, vsx), _mm_and_si128(step_y, vsy)));
      }
      _mm_store_si128(reinterpret_cast<__m128i*>(err), e);
      _mm_store_si128(reinterpret_cast<__m128i*>(index), at);
      bool refilled = true;
      for (int l = 0; l < 4; ++l)
      {
        lanes[l].err = err[l];
        lanes[l].index = index[l];
        lanes[l].left -= steps + 1;
        if (lanes[l].left < 0)
        {
          if (next == n)
          {
            refilled = false;
          }
          else
          {
            lanes[l] = line(next++);
          }
        }
      }
      if (!refilled)
      {
        for (LineCursor& rest : lanes)
        {
          for (; rest.left >= 0; rest.step())
          {
            ++cover[rest.index];
          }
        }
        return;
      }
    }
  }
#endif
  for (; next < n; ++next)
  {
    for (LineCursor c = line(next); c.left >= 0; c.step())
    {
      ++cover[c.index];
    }
  }
}

/// Sorts rays (x0, y0, x1, y1 lexicographic) and drops repeats, counting each ray's copies in
/// counts (parallel to the rays left). Rays within 65536 cells of each other, as in any real map,
/// are packed into one 64-bit key in that same order and radix-sorted: a hundred thousand rays
/// per cloud made std::sort the grid's largest cost.
void sortUnique(std::vector<GridBuilder::Ray>& rays, std::vector<std::uint32_t>& counts)
{
  counts.clear();
  if (rays.empty())
  {
    return;
  }
  std::int64_t lo = std::numeric_limits<std::int64_t>::max(), hi = std::numeric_limits<std::int64_t>::lowest();
  for (const auto& r : rays)
  {
    lo = std::min<std::int64_t>({ lo, r.x0, r.y0, r.x1, r.y1 });
    hi = std::max<std::int64_t>({ hi, r.x0, r.y0, r.x1, r.y1 });
  }
  if (hi - lo >= 65536)
  {
    std::sort(rays.begin(), rays.end());
    std::size_t out = 0;
    for (std::size_t i = 0; i < rays.size(); ++i)
    {
      if (out > 0 && rays[out - 1] == rays[i])
      {
        ++counts.back();
      }
      else
      {
        rays[out++] = rays[i];
        counts.push_back(1);
      }
    }
    rays.resize(out);
    return;
  }
  // Fields of only as many bits as the span needs: the sort passes over fewer digits.
  int b = 1;
  while (b < 16 && (hi - lo) >> b != 0)
  {
    ++b;
  }
  const std::uint64_t mask = (std::uint64_t{ 1 } << b) - 1;
  std::vector<std::uint64_t> keys;
  keys.reserve(rays.size());
  for (const auto& r : rays)
  {
    keys.push_back(static_cast<std::uint64_t>(r.x0 - lo) << (3 * b) | static_cast<std::uint64_t>(r.y0 - lo) << (2 * b) |
                   static_cast<std::uint64_t>(r.x1 - lo) << b | static_cast<std::uint64_t>(r.y1 - lo));
  }
  radixSort(keys);
  rays.clear();
  for (std::size_t i = 0; i < keys.size(); ++i)
  {
    if (i > 0 && keys[i] == keys[i - 1])
    {
      ++counts.back();
      continue;
    }
    const std::uint64_t k = keys[i];
    rays.push_back(GridBuilder::Ray{ static_cast<std::int32_t>((k >> (3 * b)) + lo), static_cast<std::int32_t>(((k >> (2 * b)) & mask) + lo),
                                     static_cast<std::int32_t>(((k >> b) & mask) + lo), static_cast<std::int32_t>((k & mask) + lo) });
    counts.push_back(1);
  }
}

/// Sorts (y, x) cells and drops repeats, counting each cell's copies in counts. update() keeps cell indices within +-(1e9 + 1), so the
/// offsets from the minima fit 32 bits each and one 64-bit key per cell, radix-sorted, orders them
/// as the pairs do: std::sort of ~45k pairs took ~1.5 ms per full rebuild.
void sortUniqueCells(std::vector<std::pair<std::int64_t, std::int64_t>>& cells, std::vector<std::uint32_t>& counts)
{
  counts.clear();
  if (cells.empty())
  {
    return;
  }
  std::int64_t min_y = cells.front().first, min_x = cells.front().second;
  for (const auto& c : cells)
  {
    min_y = std::min(min_y, c.first);
    min_x = std::min(min_x, c.second);
  }
  std::vector<std::uint64_t> keys;
  keys.reserve(cells.size());
  for (const auto& c : cells)
  {
    keys.push_back(static_cast<std::uint64_t>(c.first - min_y) << 32 | static_cast<std::uint64_t>(c.second - min_x));
  }
  radixSort(keys);
  cells.clear();
  for (std::size_t i = 0; i < keys.size(); ++i)
  {
    if (i > 0 && keys[i] == keys[i - 1])
    {
      ++counts.back();
      continue;
    }
    cells.emplace_back(static_cast<std::int64_t>(keys[i] >> 32) + min_y, static_cast<std::int64_t>(keys[i] & 0xffffffffu) + min_x);
    counts.push_back(1);
  }
}

cv::Point canonicalA(const cv::Point& a, const cv::Point& b)
{
  return (a.x < b.x || (a.x == b.x && a.y < b.y)) ? a : b;
}
}  // namespace


int OccupancyGrid::colOf(double x_m) const
{
  return static_cast<int>(std::floor((x_m - origin_x_m) / resolution_m));
}

int OccupancyGrid::rowOf(double y_m) const
{
  return static_cast<int>(std::floor((y_m - origin_y_m) / resolution_m));
}

std::size_t OccupancyGrid::count(std::int8_t value) const
{
  return static_cast<std::size_t>(std::count(data.begin(), data.end(), value));
}

void GridBuilderConfig::validate() const
{
  if (!(resolution_m > 0.0) || !std::isfinite(resolution_m))
  {
    throw std::invalid_argument("GridBuilderConfig: resolution_m must be finite and > 0");
  }
  if (tile_size_cells < 4 || tile_size_cells > 4096)
  {
    throw std::invalid_argument("GridBuilderConfig: tile_size_cells must be in [4, 4096]");
  }
  if (!(padding_m >= 0.0) || !std::isfinite(padding_m))
  {
    throw std::invalid_argument("GridBuilderConfig: padding_m must be finite and >= 0");
  }
  if (max_cells < 1)
  {
    throw std::invalid_argument("GridBuilderConfig: max_cells must be >= 1");
  }
  if (clear_segment_min_rays < 0)
  {
    throw std::invalid_argument("GridBuilderConfig: clear_segment_min_rays must be >= 0");
  }
  alpha.validate();
}

GridBuilder::GridBuilder(const GridBuilderConfig& config) : config_(config)
{
  config_.validate();
  reset();
}

void GridBuilder::reset()
{
  grid_ = OccupancyGrid();
  grid_.resolution_m = config_.resolution_m;
  cell0_x_ = cell0_y_ = 0;
  tiles_x_ = tiles_y_ = 0;
  alpha_m_ = config_.alpha.alpha_m;
  tile_cells_.clear();
  rays_.clear();
  ray_count_.clear();
  ray_cover_.clear();
  obstacle_count_.clear();
  last_shape_ = AlphaShapeResult();
}

GridUpdate GridBuilder::update(const PointList2D& obstacles, std::vector<FreeRay> rays)
{
  GridUpdate result;
  const double res = config_.resolution_m;
  const int tile = config_.tile_size_cells;

  std::vector<std::pair<std::int64_t, std::int64_t>> cells;  // (y, x) absolute
  cells.reserve(obstacles.size());
  std::int64_t cx = 0, cy = 0;
  for (const auto& p : obstacles)
  {
    if (toCell(p, cx, cy))
    {
      cells.emplace_back(cy, cx);
    }
  }
  std::vector<std::uint32_t> cell_counts;  // obstacle points per cell
  sortUniqueCells(cells, cell_counts);

  std::vector<Ray> new_rays;
  new_rays.reserve(rays.size());
  Ray converted;
  for (const auto& r : rays)
  {
    if (toRay(r, converted))
    {
      new_rays.push_back(converted);
    }
  }
  std::vector<FreeRay>().swap(rays);  // done with: its pages serve the arrays below
  std::vector<std::uint32_t> new_counts;
  sortUnique(new_rays, new_counts);
  result.n_obstacle_cells = cells.size();
  result.n_rays = new_rays.size();

  if (cells.empty() && new_rays.empty())
  {
    const bool had_grid = !grid_.empty();
    reset();
    result.full_rebuild = true;
    result.status = had_grid ? "no obstacle points and no free rays: the grid was cleared"
                             : "no obstacle points and no free rays: empty grid";
    result.alpha_m = alpha_m_;
    return result;
  }

  // Extent of the data in absolute cells, padded and snapped outwards to whole tiles.
  std::int64_t min_x = std::numeric_limits<std::int64_t>::max(), min_y = min_x;
  std::int64_t max_x = std::numeric_limits<std::int64_t>::lowest(), max_y = max_x;
  auto extend = [&](std::int64_t x, std::int64_t y) {
    min_x = std::min(min_x, x);
    max_x = std::max(max_x, x);
    min_y = std::min(min_y, y);
    max_y = std::max(max_y, y);
  };
  for (const auto& c : cells)
  {
    extend(c.second, c.first);
  }
  for (const auto& r : new_rays)
  {
    extend(r.x0, r.y0);
    extend(r.x1, r.y1);
  }
  const std::int64_t pad = static_cast<std::int64_t>(std::ceil(config_.padding_m / res));
  std::int64_t tx0 = floorDiv(min_x - pad, tile), tx1 = floorDiv(max_x + pad, tile);
  std::int64_t ty0 = floorDiv(min_y - pad, tile), ty1 = floorDiv(max_y + pad, tile);

  bool full = grid_.empty();
  if (!full)
  {
    const std::int64_t cur_tx0 = cell0_x_ / tile, cur_ty0 = cell0_y_ / tile;
    const std::int64_t cur_tx1 = cur_tx0 + tiles_x_ - 1, cur_ty1 = cur_ty0 + tiles_y_ - 1;
    if (tx0 < cur_tx0 || ty0 < cur_ty0 || tx1 > cur_tx1 || ty1 > cur_ty1)
    {
      full = true;
      tx0 = std::min(tx0, cur_tx0);
      ty0 = std::min(ty0, cur_ty0);
      tx1 = std::max(tx1, cur_tx1);
      ty1 = std::max(ty1, cur_ty1);
    }
    else
    {
      tx0 = cur_tx0;
      ty0 = cur_ty0;
      tx1 = cur_tx1;
      ty1 = cur_ty1;
    }
  }
  const double n_cells = static_cast<double>(tx1 - tx0 + 1) * tile * static_cast<double>(ty1 - ty0 + 1) * tile;
  if (n_cells > static_cast<double>(config_.max_cells))
  {
    char buf[200];
    std::snprintf(buf, sizeof(buf), "the data spans %.0f x %.0f m, which needs %.3g cells (> max_cells %d); grid unchanged",
                  static_cast<double>(max_x - min_x + 1) * res, static_cast<double>(max_y - min_y + 1) * res, n_cells,
                  config_.max_cells);
    result.ok = false;
    result.status = buf;
    result.alpha_m = alpha_m_;
    return result;
  }

  std::vector<std::uint8_t> write;
  if (full)
  {
    std::vector<std::uint8_t> old_data;
    tiles_x_ = static_cast<int>(tx1 - tx0 + 1);
    tiles_y_ = static_cast<int>(ty1 - ty0 + 1);
    cell0_x_ = tx0 * tile;
    cell0_y_ = ty0 * tile;
    grid_.resolution_m = res;
    grid_.width = tiles_x_ * tile;
    grid_.height = tiles_y_ * tile;
    grid_.origin_x_m = static_cast<double>(cell0_x_) * res;
    grid_.origin_y_m = static_cast<double>(cell0_y_) * res;
    grid_.data.assign(static_cast<std::size_t>(grid_.width) * grid_.height, OccupancyGrid::kUnknown);
    if (config_.alpha.auto_alpha)
    {
      PointList2D centres;
      centres.reserve(cells.size());
      for (const auto& c : cells)
      {
        centres.emplace_back((static_cast<double>(c.second) + 0.5) * res, (static_cast<double>(c.first) + 0.5) * res);
      }
      alpha_m_ = automaticAlpha(centres, config_.alpha, res);
    }
    else
    {
      alpha_m_ = config_.alpha.alpha_m;
    }
  }
  const int n_tiles = tiles_x_ * tiles_y_;

  // Obstacle cells per tile, as sorted local ids.
  std::vector<std::vector<std::uint32_t>> tile_cells(static_cast<std::size_t>(n_tiles));
  for (const auto& c : cells)
  {
    const int col = static_cast<int>(c.second - cell0_x_);
    const int row = static_cast<int>(c.first - cell0_y_);
    const int t = (row / tile) * tiles_x_ + col / tile;
    tile_cells[static_cast<std::size_t>(t)].push_back(static_cast<std::uint32_t>((row % tile) * tile + col % tile));
  }
  for (auto& v : tile_cells)
  {
    std::sort(v.begin(), v.end());
  }

  write.assign(static_cast<std::size_t>(n_tiles), 0);
  // Calls visit(col, row) for the grid cells of a ray, which always lies inside the grid: its end
  // cells are part of the extent the grid was sized to.
  auto walkRay = [&](const Ray& r, auto visit) {
    bresenham(static_cast<int>(r.x0 - cell0_x_), static_cast<int>(r.y0 - cell0_y_), static_cast<int>(r.x1 - cell0_x_),
              static_cast<int>(r.y1 - cell0_y_), visit);
  };
  if (full)
  {
    std::fill(write.begin(), write.end(), 1);
    ray_cover_.assign(grid_.data.size(), 0);
    coverLines(
        new_rays.size(),
        [&](std::size_t k) {
          const Ray& r = new_rays[k];
          return LineCursor(static_cast<int>(r.x0 - cell0_x_), static_cast<int>(r.y0 - cell0_y_), static_cast<int>(r.x1 - cell0_x_),
                            static_cast<int>(r.y1 - cell0_y_), grid_.width);
        },
        ray_cover_.data());
  }
  else
  {
    std::vector<std::uint8_t> dirty_occ(static_cast<std::size_t>(n_tiles), 0);
    for (int t = 0; t < n_tiles; ++t)
    {
      dirty_occ[static_cast<std::size_t>(t)] = tile_cells[static_cast<std::size_t>(t)] != tile_cells_[static_cast<std::size_t>(t)];
    }
    markAroundDirty(dirty_occ, write);
    std::vector<Ray> removed, added;
    std::set_difference(rays_.begin(), rays_.end(), new_rays.begin(), new_rays.end(), std::back_inserter(removed));
    std::set_difference(new_rays.begin(), new_rays.end(), rays_.begin(), rays_.end(), std::back_inserter(added));
    auto cover = [&](const Ray& r, bool add) {
      walkRay(r, [&](int col, int row) {
        std::uint32_t& count = ray_cover_[static_cast<std::size_t>(row) * grid_.width + col];
        count = add ? count + 1 : count - 1;
        write[static_cast<std::size_t>((row / tile) * tiles_x_ + col / tile)] = 1;
      });
    };
    for (const auto& r : removed)
    {
      cover(r, false);
    }
    for (const auto& r : added)
    {
      cover(r, true);
    }
  }
  tile_cells_.swap(tile_cells);
  rays_.swap(new_rays);
  ray_count_.swap(new_counts);
  // How many obstacle points each cell holds: what an update by a change counts down and up.
  obstacle_count_.assign(grid_.data.size(), 0);
  for (std::size_t i = 0; i < cells.size(); ++i)
  {
    obstacle_count_[static_cast<std::size_t>(cells[i].first - cell0_y_) * grid_.width +
                    static_cast<std::size_t>(cells[i].second - cell0_x_)] = cell_counts[i];
  }
  return finish(write, full, result);
}

bool GridBuilder::toCell(const Eigen::Vector2d& p, std::int64_t& x, std::int64_t& y) const
{
  // Reject coordinates whose cell index would not fit comfortably in 32 bits.
  const double res = config_.resolution_m, limit = 1e9 * res;
  if (!p.allFinite() || std::abs(p.x()) > limit || std::abs(p.y()) > limit)
  {
    return false;
  }
  x = static_cast<std::int64_t>(std::floor(p.x() / res));
  y = static_cast<std::int64_t>(std::floor(p.y() / res));
  return true;
}

bool GridBuilder::toRay(const FreeRay& r, Ray& out) const
{
  std::int64_t ax = 0, ay = 0, bx = 0, by = 0;
  if (!toCell(r.from, ax, ay) || !toCell(r.to, bx, by))
  {
    return false;
  }
  if (bx < ax || (bx == ax && by < ay))
  {
    std::swap(ax, bx);
    std::swap(ay, by);
  }
  out = Ray{ static_cast<std::int32_t>(ax), static_cast<std::int32_t>(ay), static_cast<std::int32_t>(bx),
             static_cast<std::int32_t>(by) };
  return true;
}

GridUpdate GridBuilder::update(const PointList2D& obstacles, const std::function<std::vector<FreeRay>()>& rays,
                               const GridChange& change)
{
  if (grid_.empty() || obstacle_count_.size() != grid_.data.size())
  {
    return update(obstacles, rays());
  }
  const double res = config_.resolution_m;
  const int tile = config_.tile_size_cells;
  // What came must lie where update(obstacles, rays) would not grow the grid: inside it by the padding.
  const std::int64_t pad = static_cast<std::int64_t>(std::ceil(config_.padding_m / res));
  const std::int64_t tx0 = cell0_x_ / tile, ty0 = cell0_y_ / tile;
  auto fits = [&](std::int64_t x, std::int64_t y) {
    return floorDiv(x - pad, tile) >= tx0 && floorDiv(y - pad, tile) >= ty0 && floorDiv(x + pad, tile) < tx0 + tiles_x_ &&
           floorDiv(y + pad, tile) < ty0 + tiles_y_;
  };
  std::vector<Ray> rays_removed, rays_added;
  Ray ray;
  for (const auto& r : change.rays_removed)
  {
    if (toRay(r, ray))
    {
      rays_removed.push_back(ray);
    }
  }
  for (const auto& r : change.rays_added)
  {
    if (toRay(r, ray))
    {
      if (!fits(ray.x0, ray.y0) || !fits(ray.x1, ray.y1))
      {
        return update(obstacles, rays());
      }
      rays_added.push_back(ray);
    }
  }
  std::int64_t x = 0, y = 0;
  for (const auto& p : change.obstacles_added)
  {
    if (toCell(p, x, y) && !fits(x, y))
    {
      return update(obstacles, rays());
    }
  }

  GridUpdate result;
  const int n_tiles = tiles_x_ * tiles_y_;
  std::vector<std::uint8_t> write(static_cast<std::size_t>(n_tiles), 0), dirty_occ(write.size(), 0);
  bool consistent = true;
  auto obstacle = [&](const Eigen::Vector2d& p, int sign) {
    std::int64_t cx = 0, cy = 0;
    if (!toCell(p, cx, cy))
    {
      return;
    }
    const int col = static_cast<int>(cx - cell0_x_), row = static_cast<int>(cy - cell0_y_);
    if (col < 0 || row < 0 || col >= grid_.width || row >= grid_.height)
    {
      consistent = false;  // a removed point the grid never held
      return;
    }
    std::uint32_t& count = obstacle_count_[static_cast<std::size_t>(row) * grid_.width + col];
    if (sign < 0 && count == 0)
    {
      consistent = false;
      return;
    }
    count += sign > 0 ? 1 : static_cast<std::uint32_t>(-1);
    if ((sign > 0 && count == 1) || (sign < 0 && count == 0))
    {
      const int t = (row / tile) * tiles_x_ + col / tile;
      std::vector<std::uint32_t>& ids = tile_cells_[static_cast<std::size_t>(t)];
      const std::uint32_t id = static_cast<std::uint32_t>((row % tile) * tile + col % tile);
      const auto at = std::lower_bound(ids.begin(), ids.end(), id);
      if (sign > 0)
      {
        ids.insert(at, id);
      }
      else
      {
        ids.erase(at);
      }
      dirty_occ[static_cast<std::size_t>(t)] = 1;
    }
  };
  for (const auto& p : change.obstacles_removed)
  {
    obstacle(p, -1);
  }
  for (const auto& p : change.obstacles_added)
  {
    obstacle(p, +1);
  }
  auto cover = [&](const Ray& r, bool add) {
    bresenham(static_cast<int>(r.x0 - cell0_x_), static_cast<int>(r.y0 - cell0_y_), static_cast<int>(r.x1 - cell0_x_),
              static_cast<int>(r.y1 - cell0_y_), [&](int col, int row) {
                std::uint32_t& count = ray_cover_[static_cast<std::size_t>(row) * grid_.width + col];
                count = add ? count + 1 : count - 1;
                write[static_cast<std::size_t>((row / tile) * tiles_x_ + col / tile)] = 1;
              });
  };
  // A distinct ray covers its cells once, however many copies of it there are.
  std::size_t n_emptied = 0;  // distinct rays left with no copy
  for (const Ray& r : rays_removed)
  {
    const auto it = std::lower_bound(rays_.begin(), rays_.end(), r);
    if (it == rays_.end() || !(*it == r) || ray_count_[static_cast<std::size_t>(it - rays_.begin())] == 0)
    {
      consistent = false;
      continue;
    }
    if (--ray_count_[static_cast<std::size_t>(it - rays_.begin())] == 0)
    {
      ++n_emptied;
      cover(r, false);
    }
  }
  std::sort(rays_added.begin(), rays_added.end());
  std::vector<Ray> inserted;
  std::vector<std::uint32_t> inserted_count;
  for (const Ray& r : rays_added)
  {
    const auto it = std::lower_bound(rays_.begin(), rays_.end(), r);
    if (it != rays_.end() && *it == r)
    {
      if (ray_count_[static_cast<std::size_t>(it - rays_.begin())]++ == 0)
      {
        --n_emptied;
        cover(r, true);
      }
    }
    else if (!inserted.empty() && inserted.back() == r)
    {
      ++inserted_count.back();
    }
    else
    {
      inserted.push_back(r);
      inserted_count.push_back(1);
      cover(r, true);
    }
  }
  if (!consistent)
  {
    // The change does not follow from what this builder holds: start from the lists.
    reset();
    return update(obstacles, rays());
  }
  // Rays whose copies are all gone leave the list (a pass forward), new ones join it (a merge from
  // the back), in place: the list keeps its memory from one update to the next.
  if (n_emptied > 0 || !inserted.empty())
  {
    std::size_t kept = 0;
    for (std::size_t i = 0; i < rays_.size(); ++i)
    {
      if (ray_count_[i] > 0)
      {
        rays_[kept] = rays_[i];
        ray_count_[kept] = ray_count_[i];
        ++kept;
      }
    }
    const std::size_t total = kept + inserted.size();
    rays_.resize(total);
    ray_count_.resize(total);
    for (std::size_t i = kept, j = inserted.size(), w = total; j > 0;)
    {
      --w;
      if (i > 0 && inserted[j - 1] < rays_[i - 1])
      {
        --i;
        rays_[w] = rays_[i];
        ray_count_[w] = ray_count_[i];
      }
      else
      {
        --j;
        rays_[w] = inserted[j];
        ray_count_[w] = inserted_count[j];
      }
    }
  }
  markAroundDirty(dirty_occ, write);
  result.n_rays = rays_.size();
  result.n_obstacle_cells = 0;
  for (const auto& ids : tile_cells_)
  {
    result.n_obstacle_cells += ids.size();
  }
  return finish(write, false, result);
}

int GridBuilder::marginTiles() const
{
  return static_cast<int>(std::ceil((2.0 * alpha_m_ / config_.resolution_m + 2.0) / config_.tile_size_cells));
}

void GridBuilder::markAroundDirty(const std::vector<std::uint8_t>& dirty, std::vector<std::uint8_t>& write) const
{
  const int margin = marginTiles();
  for (int ty = 0; ty < tiles_y_; ++ty)
  {
    for (int tx = 0; tx < tiles_x_; ++tx)
    {
      if (!dirty[static_cast<std::size_t>(ty * tiles_x_ + tx)])
      {
        continue;
      }
      for (int y = std::max(0, ty - margin); y <= std::min(tiles_y_ - 1, ty + margin); ++y)
      {
        for (int x = std::max(0, tx - margin); x <= std::min(tiles_x_ - 1, tx + margin); ++x)
        {
          write[static_cast<std::size_t>(y * tiles_x_ + x)] = 1;
        }
      }
    }
  }
}

GridUpdate GridBuilder::finish(const std::vector<std::uint8_t>& write, bool full, GridUpdate result)
{
  const int tile = config_.tile_size_cells;
  const int n_tiles = tiles_x_ * tiles_y_;
  const int margin = marginTiles();

  // One window: the bounding box of the tiles to write, plus the alpha-shape context margin.
  int wx0 = tiles_x_, wy0 = tiles_y_, wx1 = -1, wy1 = -1;
  for (int ty = 0; ty < tiles_y_; ++ty)
  {
    for (int tx = 0; tx < tiles_x_; ++tx)
    {
      if (write[static_cast<std::size_t>(ty * tiles_x_ + tx)])
      {
        wx0 = std::min(wx0, tx);
        wx1 = std::max(wx1, tx);
        wy0 = std::min(wy0, ty);
        wy1 = std::max(wy1, ty);
      }
    }
  }
  result.full_rebuild = full;
  result.alpha_m = alpha_m_;
  if (wx1 >= 0)
  {
    wx0 = std::max(0, wx0 - margin);
    wy0 = std::max(0, wy0 - margin);
    wx1 = std::min(tiles_x_ - 1, wx1 + margin);
    wy1 = std::min(tiles_y_ - 1, wy1 + margin);
    const Window window{ wx0 * tile, wy0 * tile, (wx1 - wx0 + 1) * tile, (wy1 - wy0 + 1) * tile };
    // A full rebuild changes every tile it writes: nothing to compare with.
    const std::vector<std::int8_t> before = full ? std::vector<std::int8_t>() : grid_.data;
    recomputeWindow(window, write, alpha_m_, full);
    int c0 = grid_.width, r0 = grid_.height, c1 = 0, r1 = 0;
    for (int ty = 0; ty < tiles_y_; ++ty)
    {
      for (int tx = 0; tx < tiles_x_; ++tx)
      {
        if (!write[static_cast<std::size_t>(ty * tiles_x_ + tx)])
        {
          continue;
        }
        result.recomputed_tiles.push_back(TileIndex{ tx, ty });
        bool changed = full;
        for (int row = ty * tile; row < (ty + 1) * tile && !changed; ++row)
        {
          const std::size_t off = static_cast<std::size_t>(row) * grid_.width + static_cast<std::size_t>(tx) * tile;
          changed = !std::equal(before.begin() + static_cast<std::ptrdiff_t>(off),
                                before.begin() + static_cast<std::ptrdiff_t>(off + tile),
                                grid_.data.begin() + static_cast<std::ptrdiff_t>(off));
        }
        if (changed)
        {
          result.changed_tiles.push_back(TileIndex{ tx, ty });
          c0 = std::min(c0, tx * tile);
          r0 = std::min(r0, ty * tile);
          c1 = std::max(c1, (tx + 1) * tile);
          r1 = std::max(r1, (ty + 1) * tile);
        }
      }
    }
    if (!result.changed_tiles.empty())
    {
      result.min_col = c0;
      result.min_row = r0;
      result.max_col = c1;
      result.max_row = r1;
    }
  }
  char buf[200];
  std::snprintf(buf, sizeof(buf), "%s: %zu obstacle cells, %zu rays, %zu/%d tiles recomputed, %zu changed, alpha %.3f m",
                full ? "full rebuild" : "incremental update", result.n_obstacle_cells, result.n_rays,
                result.recomputed_tiles.size(), n_tiles, result.changed_tiles.size(), alpha_m_);
  result.status = buf;
  return result;
}

void GridBuilder::recomputeWindow(const Window& window, const std::vector<std::uint8_t>& write, double alpha_m,
                                  bool keep_shape)
{
  const int tile = config_.tile_size_cells;
  const double res = config_.resolution_m;
  // Obstacle cell centres inside the window, in window pixel coordinates (one per cell).
  PointList2D points;
  cv::Mat hit = cv::Mat::zeros(window.rows, window.cols, CV_8UC1);
  for (int ty = window.row0 / tile; ty < (window.row0 + window.rows) / tile; ++ty)
  {
    for (int tx = window.col0 / tile; tx < (window.col0 + window.cols) / tile; ++tx)
    {
      for (std::uint32_t id : tile_cells_[static_cast<std::size_t>(ty * tiles_x_ + tx)])
      {
        const int col = tx * tile + static_cast<int>(id % tile) - window.col0;
        const int row = ty * tile + static_cast<int>(id / tile) - window.row0;
        points.emplace_back(col, row);
        hit.at<std::uint8_t>(row, col) = 1;
      }
    }
  }
  const AlphaShapeResult shape = computeAlphaShape(points, alpha_m / res);
  auto toCv = [](const Eigen::Vector2d& p) {
    return cv::Point(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
  };
  // Cells the shape covers apart from the cells with points: kArea inside or on the rings, else
  // kSegment on a singular edge (two points joined with nothing between them).
  constexpr std::uint8_t kArea = 1, kSegment = 2;
  cv::Mat filled = cv::Mat::zeros(window.rows, window.cols, CV_8UC1);
  std::vector<std::vector<cv::Point>> polygons;
  polygons.reserve(shape.rings.size());
  for (const auto& ring : shape.rings)
  {
    std::vector<cv::Point> poly;
    poly.reserve(ring.size());
    for (const auto& p : ring)
    {
      poly.push_back(toCv(p));
    }
    polygons.push_back(std::move(poly));
  }
  if (!polygons.empty())
  {
    cv::fillPoly(filled, polygons, cv::Scalar(kArea), cv::LINE_8);
  }
  auto drawEdge = [&](const cv::Point& a, const cv::Point& b, std::uint8_t mark) {
    const cv::Point p = canonicalA(a, b);
    const cv::Point q = (p == a) ? b : a;
    bresenham(p.x, p.y, q.x, q.y, [&](int x, int y) {
      std::uint8_t& m = filled.at<std::uint8_t>(y, x);
      m = m == 0 ? mark : std::min(m, mark);
    });
  };
  for (const auto& poly : polygons)
  {
    for (std::size_t i = 0; i < poly.size(); ++i)
    {
      drawEdge(poly[i], poly[(i + 1) % poly.size()], kArea);
    }
  }
  for (const auto& s : shape.segments)
  {
    drawEdge(toCv(s.first), toCv(s.second), kSegment);
  }

  const std::uint32_t clear_segment = static_cast<std::uint32_t>(config_.clear_segment_min_rays);
  for (int row = 0; row < window.rows; ++row)
  {
    const int grow = window.row0 + row;
    const std::uint8_t* hit_row = hit.ptr<std::uint8_t>(row);
    const std::uint8_t* fill_row = filled.ptr<std::uint8_t>(row);
    const std::uint32_t* cover_row = ray_cover_.data() + static_cast<std::size_t>(grow) * grid_.width + window.col0;
    for (int col = 0; col < window.cols; ++col)
    {
      const int gcol = window.col0 + col;
      if (!write[static_cast<std::size_t>((grow / tile) * tiles_x_ + gcol / tile)])
      {
        continue;
      }
      std::int8_t v = OccupancyGrid::kUnknown;
      if (hit_row[col] || fill_row[col] == kArea ||
          (fill_row[col] == kSegment && (clear_segment == 0 || cover_row[col] < clear_segment)))
      {
        v = OccupancyGrid::kOccupied;
      }
      else if (cover_row[col] > 0)
      {
        v = OccupancyGrid::kFree;
      }
      grid_.data[static_cast<std::size_t>(grow) * grid_.width + gcol] = v;
    }
  }

  if (keep_shape)
  {
    // Back to map metres: pixel (c, r) is the centre of grid cell (col0 + c, row0 + r).
    last_shape_ = AlphaShapeResult();
    last_shape_.alpha_m = alpha_m;
    auto toMap = [&](const Eigen::Vector2d& p) {
      return Eigen::Vector2d(grid_.origin_x_m + (window.col0 + p.x() + 0.5) * res,
                             grid_.origin_y_m + (window.row0 + p.y() + 0.5) * res);
    };
    for (const auto& ring : shape.rings)
    {
      std::vector<Eigen::Vector2d> m;
      m.reserve(ring.size());
      for (const auto& p : ring)
      {
        m.push_back(toMap(p));
      }
      last_shape_.rings.push_back(std::move(m));
    }
    for (const auto& s : shape.segments)
    {
      last_shape_.segments.emplace_back(toMap(s.first), toMap(s.second));
    }
  }
}

}  // namespace sparse_nav
