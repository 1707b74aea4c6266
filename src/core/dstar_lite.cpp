#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "sparse_nav/core/grid_planner.h"

namespace sparse_nav
{
namespace
{
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kDx[8] = { 1, 0, -1, 0, 1, -1, -1, 1 };
constexpr int kDy[8] = { 0, 1, 0, -1, 1, 1, -1, -1 };

void checkCell(const PlanningGrid& grid, const Cell& c, const char* what)
{
  if (!grid.inBounds(c.x, c.y))
  {
    throw std::out_of_range(std::string("DStarLite: ") + what + " (" + std::to_string(c.x) + ", " +
                            std::to_string(c.y) + ") is outside the grid");
  }
}
}  // namespace

DStarLite::DStarLite(PlanningGrid grid, const Cell& start, const Cell& goal)
  : grid_(std::move(grid)), start_(start), goal_(goal), last_(start)
{
  if (grid_.width() <= 0 || grid_.height() <= 0)
  {
    throw std::invalid_argument("DStarLite: empty grid");
  }
  checkCell(grid_, start, "start");
  checkCell(grid_, goal, "goal");
  const std::size_t n = static_cast<std::size_t>(grid_.width()) * grid_.height();
  g_.assign(n, kInf);
  rhs_.assign(n, kInf);
  heap_pos_.assign(n, -1);
  heap_.reserve(1024);
  const std::size_t t = grid_.index(goal.x, goal.y);
  rhs_[t] = 0.0;
  heapPush(t, calculateKey(t));
}

double DStarLite::heuristic(std::size_t s) const
{
  const int w = grid_.width();
  return octileDistance(start_, Cell{ static_cast<int>(s % w), static_cast<int>(s / w) });
}

DStarLite::Key DStarLite::calculateKey(std::size_t s) const
{
  const double m = std::min(g_[s], rhs_[s]);
  return Key{ m + heuristic(s) + k_m_, m };
}

double DStarLite::bestRhs(std::size_t s) const
{
  const int w = grid_.width();
  const int x = static_cast<int>(s % w), y = static_cast<int>(s / w);
  double best = kInf;
  if (!grid_.traversable(x, y))
  {
    return best;
  }
  for (int k = 0; k < 8; ++k)
  {
    const int nx = x + kDx[k], ny = y + kDy[k];
    if (!grid_.inBounds(nx, ny))
    {
      continue;
    }
    const double gn = g_[grid_.index(nx, ny)];
    if (gn == kInf)
    {
      continue;
    }
    best = std::min(best, grid_.moveCost(x, y, nx, ny) + gn);
  }
  return best;
}

void DStarLite::updateVertex(std::size_t s)
{
  const bool inconsistent = g_[s] != rhs_[s];
  if (inconsistent && inHeap(s))
  {
    heapUpdate(s, calculateKey(s));
  }
  else if (inconsistent)
  {
    heapPush(s, calculateKey(s));
  }
  else if (inHeap(s))
  {
    heapRemove(s);
  }
}

bool DStarLite::plan()
{
  expansions_ = 0;
  planned_ = true;
  if (!grid_.traversable(start_.x, start_.y) || !grid_.traversable(goal_.x, goal_.y))
  {
    return false;
  }
  const std::size_t start = grid_.index(start_.x, start_.y);
  const std::size_t goal = grid_.index(goal_.x, goal_.y);
  const int w = grid_.width();
  // The paper stops once TopKey >= key(start). Keys are sums of sqrt(2) steps added in different
  // orders, so a vertex whose key ties the start's exactly in real arithmetic can come out a few ulps
  // above it and be left unexpanded with a wrong g behind the start. Expanding every vertex whose k1
  // is within a relative 1e-9 of the start's closes that gap at the price of expanding ties.
  auto keepGoing = [&]() {
    const Key ks = calculateKey(start);
    const double tol = 1e-9 * std::max(1.0, ks.k1);
    return heap_[0].first.k1 <= ks.k1 + tol || rhs_[start] > g_[start];
  };
  while (!heap_.empty() && keepGoing())
  {
    const std::size_t u = heap_[0].second;
    const Key k_old = heap_[0].first;
    const Key k_new = calculateKey(u);
    ++expansions_;
    const int ux = static_cast<int>(u % w), uy = static_cast<int>(u / w);
    if (k_old < k_new)
    {
      heapUpdate(u, k_new);
    }
    else if (g_[u] > rhs_[u])
    {
      g_[u] = rhs_[u];
      heapRemove(u);
      for (int k = 0; k < 8; ++k)
      {
        const int sx = ux + kDx[k], sy = uy + kDy[k];
        if (!grid_.inBounds(sx, sy))
        {
          continue;
        }
        const std::size_t s = grid_.index(sx, sy);
        if (s != goal)
        {
          rhs_[s] = std::min(rhs_[s], grid_.moveCost(sx, sy, ux, uy) + g_[u]);
        }
        updateVertex(s);
      }
    }
    else
    {
      const double g_old = g_[u];
      g_[u] = kInf;
      for (int k = 0; k <= 8; ++k)
      {
        const int sx = k < 8 ? ux + kDx[k] : ux, sy = k < 8 ? uy + kDy[k] : uy;
        if (!grid_.inBounds(sx, sy))
        {
          continue;
        }
        const std::size_t s = grid_.index(sx, sy);
        // rhs(s) <= c(s, u) + g_old always holds, so ">=" is the paper's equality test.
        if (s != goal && (s == u || !(rhs_[s] < grid_.moveCost(sx, sy, ux, uy) + g_old)))
        {
          rhs_[s] = bestRhs(s);
        }
        updateVertex(s);
      }
    }
  }
  return rhs_[start] < kInf;
}

void DStarLite::updateCells(const std::vector<CellChange>& changes)
{
  const std::vector<std::size_t> changed = grid_.setStates(changes);
  if (changed.empty())
  {
    return;
  }
  planned_ = false;
  const std::size_t goal = grid_.index(goal_.x, goal_.y);
  const int w = grid_.width();
  // A changed multiplier changes every move touching the cell, and the diagonal moves between two of
  // its neighbours that pass its corner; all their tails are the cell or one of its neighbours.
  std::vector<std::size_t> affected;
  affected.reserve(changed.size() * 9);
  for (const std::size_t c : changed)
  {
    const int cx = static_cast<int>(c % w), cy = static_cast<int>(c / w);
    for (int k = 0; k <= 8; ++k)
    {
      const int sx = k < 8 ? cx + kDx[k] : cx, sy = k < 8 ? cy + kDy[k] : cy;
      if (grid_.inBounds(sx, sy))
      {
        affected.push_back(grid_.index(sx, sy));
      }
    }
  }
  std::sort(affected.begin(), affected.end());
  affected.erase(std::unique(affected.begin(), affected.end()), affected.end());
  for (const std::size_t s : affected)
  {
    if (s != goal)
    {
      rhs_[s] = bestRhs(s);
    }
    updateVertex(s);
  }
}

void DStarLite::moveStart(const Cell& start)
{
  checkCell(grid_, start, "start");
  if (start == start_)
  {
    return;
  }
  // Keys already queued stay lower bounds when k_m grows by the heuristic distance moved.
  k_m_ += octileDistance(last_, start);
  last_ = start;
  start_ = start;
  planned_ = false;
}

void DStarLite::requirePlanned() const
{
  if (!planned_)
  {
    throw std::logic_error("DStarLite: call plan() after updateCells() or moveStart()");
  }
}

double DStarLite::cost() const
{
  requirePlanned();
  if (!grid_.traversable(start_.x, start_.y) || !grid_.traversable(goal_.x, goal_.y))
  {
    return kInf;
  }
  return rhs_[grid_.index(start_.x, start_.y)];
}

std::vector<Cell> DStarLite::path() const
{
  std::vector<Cell> out;
  if (cost() == kInf)
  {
    return out;
  }
  const std::size_t n = g_.size();
  Cell s = start_;
  out.push_back(s);
  while (s != goal_)
  {
    double best = kInf;
    Cell next = s;
    for (int k = 0; k < 8; ++k)
    {
      const int nx = s.x + kDx[k], ny = s.y + kDy[k];
      if (!grid_.inBounds(nx, ny))
      {
        continue;
      }
      const double gn = g_[grid_.index(nx, ny)];
      if (gn == kInf)
      {
        continue;
      }
      const double v = grid_.moveCost(s.x, s.y, nx, ny) + gn;
      if (v < best)  // strict: the first neighbour in the fixed order wins ties
      {
        best = v;
        next = Cell{ nx, ny };
      }
    }
    if (best == kInf || out.size() > n)
    {
      return {};
    }
    s = next;
    out.push_back(s);
  }
  return out;
}

void DStarLite::heapSwap(std::size_t a, std::size_t b)
{
  std::swap(heap_[a], heap_[b]);
  heap_pos_[heap_[a].second] = static_cast<std::int32_t>(a);
  heap_pos_[heap_[b].second] = static_cast<std::int32_t>(b);
}

void DStarLite::siftUp(std::size_t pos)
{
  while (pos > 0)
  {
    const std::size_t parent = (pos - 1) / 2;
    if (!(heap_[pos].first < heap_[parent].first))
    {
      break;
    }
    heapSwap(pos, parent);
    pos = parent;
  }
}

void DStarLite::siftDown(std::size_t pos)
{
  const std::size_t n = heap_.size();
  for (;;)
  {
    const std::size_t l = 2 * pos + 1, r = l + 1;
    std::size_t smallest = pos;
    if (l < n && heap_[l].first < heap_[smallest].first)
    {
      smallest = l;
    }
    if (r < n && heap_[r].first < heap_[smallest].first)
    {
      smallest = r;
    }
    if (smallest == pos)
    {
      return;
    }
    heapSwap(pos, smallest);
    pos = smallest;
  }
}

void DStarLite::heapPush(std::size_t s, const Key& k)
{
  heap_.emplace_back(k, static_cast<std::uint32_t>(s));
  heap_pos_[s] = static_cast<std::int32_t>(heap_.size() - 1);
  siftUp(heap_.size() - 1);
}

void DStarLite::heapUpdate(std::size_t s, const Key& k)
{
  const std::size_t pos = static_cast<std::size_t>(heap_pos_[s]);
  const Key old = heap_[pos].first;
  heap_[pos].first = k;
  if (k < old)
  {
    siftUp(pos);
  }
  else
  {
    siftDown(pos);
  }
}

void DStarLite::heapRemove(std::size_t s)
{
  const std::size_t pos = static_cast<std::size_t>(heap_pos_[s]);
  const std::size_t last = heap_.size() - 1;
  if (pos != last)
  {
    heapSwap(pos, last);
  }
  heap_.pop_back();
  heap_pos_[s] = -1;
  if (pos < heap_.size())
  {
    siftUp(pos);
    siftDown(pos);
  }
}

}  // namespace sparse_nav
