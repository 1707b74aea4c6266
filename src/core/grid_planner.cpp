#include "sparse_nav/core/grid_planner.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <string>

namespace sparse_nav
{
namespace
{
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kSqrt2 = 1.4142135623730951;
constexpr int kDx[8] = { 1, 0, -1, 0, 1, -1, -1, 1 };
constexpr int kDy[8] = { 0, 1, 0, -1, 1, 1, -1, -1 };
}  // namespace

void PlanningGridConfig::validate() const
{
  if (unknown_policy != UnknownPolicy::kFree && unknown_policy != UnknownPolicy::kCostly &&
      unknown_policy != UnknownPolicy::kBlocked)
  {
    throw std::invalid_argument("PlanningGridConfig: unknown_policy is not a known policy");
  }
  if (!(unknown_cost_multiplier >= 1.0) || !std::isfinite(unknown_cost_multiplier))
  {
    throw std::invalid_argument("PlanningGridConfig: unknown_cost_multiplier must be finite and >= 1");
  }
  if (!(inflation_radius_cells >= 0.0) || !(inflation_radius_cells <= 1000.0))
  {
    throw std::invalid_argument("PlanningGridConfig: inflation_radius_cells must be in [0, 1000]");
  }
  if (occupied_threshold < 1 || occupied_threshold > 100)
  {
    throw std::invalid_argument("PlanningGridConfig: occupied_threshold must be in [1, 100]");
  }
}

PlanningGrid::PlanningGrid(int width, int height, CellState fill, const PlanningGridConfig& config)
  : config_(config), width_(width), height_(height)
{
  config_.validate();
  if (width <= 0 || height <= 0 || static_cast<long long>(width) * height > 0x7fffffffLL)
  {
    throw std::invalid_argument("PlanningGrid: width and height must be > 0 (and fit 2^31 cells)");
  }
  const std::size_t n = static_cast<std::size_t>(width) * height;
  states_.assign(n, fill);
  blocked_near_.assign(n, 0);
  mult_.assign(n, 1.0);
  mark_.assign(n, 0);
  const int r = static_cast<int>(std::floor(config_.inflation_radius_cells));
  const double r2 = config_.inflation_radius_cells * config_.inflation_radius_cells;
  for (int dy = -r; dy <= r; ++dy)
  {
    for (int dx = -r; dx <= r; ++dx)
    {
      if (dx * dx + dy * dy <= r2 + 1e-9)
      {
        disk_.emplace_back(dx, dy);
      }
    }
  }
  for (int y = 0; y < height_; ++y)
  {
    for (int x = 0; x < width_; ++x)
    {
      if (states_[index(x, y)] != CellState::kBlocked)
      {
        continue;
      }
      for (const auto& o : disk_)
      {
        if (inBounds(x + o.first, y + o.second))
        {
          ++blocked_near_[index(x + o.first, y + o.second)];
        }
      }
    }
  }
  for (std::size_t i = 0; i < n; ++i)
  {
    recompute(i);
  }
}

PlanningGrid PlanningGrid::fromOccupancy(const OccupancyGrid& grid, const PlanningGridConfig& config)
{
  if (grid.empty() || grid.data.size() != static_cast<std::size_t>(grid.width) * grid.height)
  {
    throw std::invalid_argument("PlanningGrid::fromOccupancy: empty grid or data size != width * height");
  }
  config.validate();
  std::vector<CellChange> changes;
  for (int y = 0; y < grid.height; ++y)
  {
    for (int x = 0; x < grid.width; ++x)
    {
      const int v = grid.at(x, y);
      if (v < 0)
      {
        changes.push_back({ Cell{ x, y }, CellState::kUnknown });
      }
      else if (v >= config.occupied_threshold)
      {
        changes.push_back({ Cell{ x, y }, CellState::kBlocked });
      }
    }
  }
  PlanningGrid out(grid.width, grid.height, CellState::kFree, config);
  out.setStates(changes);
  return out;
}

void PlanningGrid::recompute(std::size_t i)
{
  if (states_[i] == CellState::kBlocked || blocked_near_[i] > 0)
  {
    mult_[i] = kInf;
  }
  else if (states_[i] == CellState::kUnknown)
  {
    switch (config_.unknown_policy)
    {
      case UnknownPolicy::kFree:
        mult_[i] = 1.0;
        break;
      case UnknownPolicy::kCostly:
        mult_[i] = config_.unknown_cost_multiplier;
        break;
      case UnknownPolicy::kBlocked:
        mult_[i] = kInf;
        break;
    }
  }
  else
  {
    mult_[i] = 1.0;
  }
}

std::vector<std::size_t> PlanningGrid::setStates(const std::vector<CellChange>& changes)
{
  for (const auto& c : changes)
  {
    if (!inBounds(c.cell.x, c.cell.y))
    {
      throw std::out_of_range("PlanningGrid::setStates: cell (" + std::to_string(c.cell.x) + ", " +
                              std::to_string(c.cell.y) + ") is outside the grid");
    }
  }
  std::vector<std::size_t> touched;
  auto touch = [&](std::size_t i) {
    if (!mark_[i])
    {
      mark_[i] = 1;
      touched.push_back(i);
    }
  };
  std::vector<double> old_mult;
  for (const auto& c : changes)
  {
    const std::size_t i = index(c.cell.x, c.cell.y);
    const CellState before = states_[i];
    if (before == c.state)
    {
      continue;
    }
    const bool was_blocked = before == CellState::kBlocked;
    const bool is_blocked = c.state == CellState::kBlocked;
    states_[i] = c.state;
    if (!mark_[i])
    {
      touch(i);
      old_mult.push_back(mult_[i]);
    }
    if (was_blocked != is_blocked)
    {
      const int delta = is_blocked ? 1 : -1;
      for (const auto& o : disk_)
      {
        const int x = c.cell.x + o.first, y = c.cell.y + o.second;
        if (inBounds(x, y))
        {
          const std::size_t j = index(x, y);
          blocked_near_[j] += delta;
          if (!mark_[j])
          {
            touch(j);
            old_mult.push_back(mult_[j]);
          }
        }
      }
    }
  }
  std::vector<std::size_t> changed;
  for (std::size_t k = 0; k < touched.size(); ++k)
  {
    const std::size_t i = touched[k];
    mark_[i] = 0;
    recompute(i);
    if (mult_[i] != old_mult[k])
    {
      changed.push_back(i);
    }
  }
  return changed;
}

double PlanningGrid::moveCost(int ax, int ay, int bx, int by) const
{
  if (!traversable(ax, ay) || !traversable(bx, by))
  {
    return kInf;
  }
  const int dx = bx - ax, dy = by - ay;
  const double ma = mult_[index(ax, ay)], mb = mult_[index(bx, by)];
  if (dx != 0 && dy != 0)
  {
    if (!traversable(ax + dx, ay) || !traversable(ax, ay + dy))
    {
      return kInf;
    }
    return kSqrt2 * 0.5 * (ma + mb);
  }
  return 0.5 * (ma + mb);
}

double octileDistance(const Cell& a, const Cell& b)
{
  const int dx = std::abs(a.x - b.x), dy = std::abs(a.y - b.y);
  const int lo = std::min(dx, dy), hi = std::max(dx, dy);
  return (hi - lo) + kSqrt2 * lo;
}

PlanResult aStar(const PlanningGrid& grid, const Cell& start, const Cell& goal)
{
  if (!grid.inBounds(start.x, start.y) || !grid.inBounds(goal.x, goal.y))
  {
    throw std::out_of_range("aStar: start or goal outside the grid");
  }
  PlanResult result;
  if (!grid.traversable(start.x, start.y) || !grid.traversable(goal.x, goal.y))
  {
    return result;
  }
  const std::size_t n = static_cast<std::size_t>(grid.width()) * grid.height();
  std::vector<double> g(n, kInf);
  std::vector<std::int32_t> parent(n, -1);
  // Indexed binary heap with decrease-key: a lazy-deletion queue held every stale duplicate and
  // spent most of the search sifting them (profiled on 1024 x 1024 maps).
  constexpr std::int32_t kClosed = -2;
  std::vector<std::int32_t> pos(n, -1);  // heap position, -1 never opened, kClosed expanded
  struct Entry
  {
    double f;
    double g;
    std::uint32_t i;
  };
  std::vector<Entry> heap;
  // (f, g, index): ties on f prefer the larger g (deeper), then the lower index; deterministic.
  auto before = [](const Entry& a, const Entry& b) {
    if (a.f != b.f)
    {
      return a.f < b.f;
    }
    if (a.g != b.g)
    {
      return a.g > b.g;
    }
    return a.i < b.i;
  };
  auto place = [&](std::size_t k, const Entry& e) {
    heap[k] = e;
    pos[e.i] = static_cast<std::int32_t>(k);
  };
  auto siftUp = [&](std::size_t k, const Entry& e) {
    while (k > 0)
    {
      const std::size_t up = (k - 1) / 2;
      if (!before(e, heap[up]))
      {
        break;
      }
      place(k, heap[up]);
      k = up;
    }
    place(k, e);
  };
  auto siftDown = [&](std::size_t k, const Entry& e) {
    const std::size_t size = heap.size();
    while (true)
    {
      std::size_t c = 2 * k + 1;
      if (c >= size)
      {
        break;
      }
      if (c + 1 < size && before(heap[c + 1], heap[c]))
      {
        ++c;
      }
      if (!before(heap[c], e))
      {
        break;
      }
      place(k, heap[c]);
      k = c;
    }
    place(k, e);
  };
  auto popTop = [&]() {
    const Entry top = heap.front();
    const Entry last = heap.back();
    heap.pop_back();
    if (!heap.empty())
    {
      siftDown(0, last);
    }
    return top;
  };
  const std::size_t s = grid.index(start.x, start.y), t = grid.index(goal.x, goal.y);
  g[s] = 0.0;
  heap.push_back({ 0.0, 0.0, 0 });
  siftUp(0, { octileDistance(start, goal), 0.0, static_cast<std::uint32_t>(s) });
  const int w = grid.width();
  while (!heap.empty())
  {
    const Entry e = popTop();
    pos[e.i] = kClosed;
    ++result.expansions;
    if (e.i == t)
    {
      break;
    }
    const int x = static_cast<int>(e.i % w), y = static_cast<int>(e.i / w);
    for (int k = 0; k < 8; ++k)
    {
      const int nx = x + kDx[k], ny = y + kDy[k];
      if (!grid.inBounds(nx, ny))
      {
        continue;
      }
      const std::size_t j = grid.index(nx, ny);
      if (pos[j] == kClosed)
      {
        continue;
      }
      const double c = grid.moveCost(x, y, nx, ny);
      if (c == kInf)
      {
        continue;
      }
      const double ng = e.g + c;
      if (ng < g[j])
      {
        g[j] = ng;
        parent[j] = static_cast<std::int32_t>(e.i);
        const Entry entry{ ng + octileDistance(Cell{ nx, ny }, goal), ng, static_cast<std::uint32_t>(j) };
        if (pos[j] < 0)
        {
          heap.push_back(entry);
          siftUp(heap.size() - 1, entry);
        }
        else
        {
          // A lower g lowers f, so the entry moves up; with f rounded to a tie, the smaller g can
          // rank it below a child instead.
          const std::size_t k = static_cast<std::size_t>(pos[j]);
          siftUp(k, entry);
          if (pos[j] == static_cast<std::int32_t>(k))
          {
            siftDown(k, entry);
          }
        }
      }
    }
  }
  if (g[t] == kInf)
  {
    return result;
  }
  result.cost = g[t];
  for (std::int64_t i = static_cast<std::int64_t>(t); i >= 0; i = parent[static_cast<std::size_t>(i)])
  {
    result.path.push_back(Cell{ static_cast<int>(i % w), static_cast<int>(i / w) });
    if (static_cast<std::size_t>(i) == s)
    {
      break;
    }
  }
  std::reverse(result.path.begin(), result.path.end());
  return result;
}

bool lineOfSight(const PlanningGrid& grid, const Cell& a, const Cell& b, double max_multiplier)
{
  auto ok = [&](int x, int y) { return grid.traversable(x, y) && grid.multiplier(x, y) <= max_multiplier; };
  if (!ok(a.x, a.y))
  {
    return false;
  }
  const int nx = std::abs(b.x - a.x), ny = std::abs(b.y - a.y);
  const int sx = b.x > a.x ? 1 : -1, sy = b.y > a.y ? 1 : -1;
  int x = a.x, y = a.y;
  int ix = 0, iy = 0;
  while (ix < nx || iy < ny)
  {
    // Compare where the segment leaves the current cell: (0.5 + ix) / nx vs (0.5 + iy) / ny.
    const long long decision =
        static_cast<long long>(1 + 2 * ix) * ny - static_cast<long long>(1 + 2 * iy) * nx;
    if (decision == 0)
    {
      // Exactly through a corner: both side cells must be passable (no corner cutting).
      if (!ok(x + sx, y) || !ok(x, y + sy))
      {
        return false;
      }
      x += sx;
      y += sy;
      ++ix;
      ++iy;
    }
    else if (decision < 0)
    {
      x += sx;
      ++ix;
    }
    else
    {
      y += sy;
      ++iy;
    }
    if (!ok(x, y))
    {
      return false;
    }
  }
  return true;
}

std::vector<Cell> smoothPath(const PlanningGrid& grid, const std::vector<Cell>& path)
{
  for (const auto& c : path)
  {
    if (!grid.inBounds(c.x, c.y))
    {
      throw std::out_of_range("smoothPath: path cell (" + std::to_string(c.x) + ", " + std::to_string(c.y) +
                              ") is outside the grid");
    }
  }
  if (path.size() <= 2)
  {
    return path;
  }
  // Greedy string pulling: from each kept waypoint, advance along the path while the straight
  // segment stays clear, and keep the last cell it reached.
  std::vector<Cell> out;
  out.push_back(path.front());
  std::size_t anchor = 0;
  while (anchor + 1 < path.size())
  {
    std::size_t best = anchor + 1;
    double window_max = std::max(grid.multiplier(path[anchor].x, path[anchor].y),
                                 grid.multiplier(path[anchor + 1].x, path[anchor + 1].y));
    for (std::size_t j = anchor + 2; j < path.size(); ++j)
    {
      window_max = std::max(window_max, grid.multiplier(path[j].x, path[j].y));
      if (!lineOfSight(grid, path[anchor], path[j], window_max))
      {
        break;
      }
      best = j;
    }
    out.push_back(path[best]);
    anchor = best;
  }
  return out;
}

}  // namespace sparse_nav
