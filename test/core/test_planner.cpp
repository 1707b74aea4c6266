#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "sparse_nav/core/grid_planner.h"

using sparse_nav::aStar;
using sparse_nav::Cell;
using sparse_nav::CellChange;
using sparse_nav::CellState;
using sparse_nav::DStarLite;
using sparse_nav::lineOfSight;
using sparse_nav::OccupancyGrid;
using sparse_nav::PlanningGrid;
using sparse_nav::PlanningGridConfig;
using sparse_nav::PlanResult;
using sparse_nav::smoothPath;
using sparse_nav::UnknownPolicy;

namespace
{
constexpr double kTol = 1e-9;
const double kSqrt2 = std::sqrt(2.0);
const double kInf = std::numeric_limits<double>::infinity();

/// Grid from rows of text, row 0 first: '.' free, '#' blocked, '?' unknown.
PlanningGrid fromText(const std::vector<std::string>& rows, const PlanningGridConfig& cfg = PlanningGridConfig())
{
  PlanningGrid g(static_cast<int>(rows[0].size()), static_cast<int>(rows.size()), CellState::kFree, cfg);
  std::vector<CellChange> changes;
  for (int y = 0; y < static_cast<int>(rows.size()); ++y)
  {
    for (int x = 0; x < static_cast<int>(rows[y].size()); ++x)
    {
      if (rows[y][x] == '#')
      {
        changes.push_back({ Cell{ x, y }, CellState::kBlocked });
      }
      else if (rows[y][x] == '?')
      {
        changes.push_back({ Cell{ x, y }, CellState::kUnknown });
      }
    }
  }
  g.setStates(changes);
  return g;
}

/// Checks that consecutive path cells are legal moves and that their costs sum to the reported cost.
void expectValidPath(const PlanningGrid& g, const std::vector<Cell>& path, const Cell& s, const Cell& t, double cost)
{
  ASSERT_FALSE(path.empty());
  EXPECT_EQ(path.front(), s);
  EXPECT_EQ(path.back(), t);
  double sum = 0.0;
  for (std::size_t i = 1; i < path.size(); ++i)
  {
    ASSERT_LE(std::abs(path[i].x - path[i - 1].x), 1);
    ASSERT_LE(std::abs(path[i].y - path[i - 1].y), 1);
    const double c = g.moveCost(path[i - 1].x, path[i - 1].y, path[i].x, path[i].y);
    ASSERT_LT(c, kInf) << "illegal move at step " << i;
    sum += c;
  }
  EXPECT_NEAR(sum, cost, kTol * std::max(1.0, cost));
}

/// Plans with both planners, checks they agree and returns the cost.
double planBoth(const PlanningGrid& g, const Cell& s, const Cell& t)
{
  const PlanResult a = aStar(g, s, t);
  DStarLite d(g, s, t);
  const bool found = d.plan();
  EXPECT_EQ(found, a.found());
  if (!a.found())
  {
    EXPECT_EQ(d.cost(), kInf);
    EXPECT_TRUE(d.path().empty());
    EXPECT_TRUE(a.path.empty());
    return kInf;
  }
  EXPECT_NEAR(d.cost(), a.cost, kTol * std::max(1.0, a.cost));
  expectValidPath(g, a.path, s, t, a.cost);
  expectValidPath(g, d.path(), s, t, d.cost());
  return a.cost;
}
}  // namespace

TEST(PlanningGridConfig, Validate)
{
  PlanningGridConfig cfg;
  EXPECT_NO_THROW(cfg.validate());
  cfg.unknown_cost_multiplier = 0.5;
  EXPECT_THROW(cfg.validate(), std::invalid_argument);
  cfg = PlanningGridConfig();
  cfg.inflation_radius_cells = -1.0;
  EXPECT_THROW(cfg.validate(), std::invalid_argument);
  cfg = PlanningGridConfig();
  cfg.occupied_threshold = 0;
  EXPECT_THROW(cfg.validate(), std::invalid_argument);
  EXPECT_THROW(PlanningGrid(0, 5), std::invalid_argument);
}

TEST(Planner, OpenGridDiagonal)
{
  for (int n : { 1, 5, 20, 63 })
  {
    PlanningGrid g(n + 1, n + 1);
    EXPECT_NEAR(planBoth(g, Cell{ 0, 0 }, Cell{ n, n }), kSqrt2 * n, kTol * n);
  }
  PlanningGrid g(30, 10);
  EXPECT_NEAR(planBoth(g, Cell{ 0, 0 }, Cell{ 29, 9 }), 20.0 + 9.0 * kSqrt2, kTol * 30);
  EXPECT_NEAR(planBoth(g, Cell{ 3, 4 }, Cell{ 3, 4 }), 0.0, kTol);
}

TEST(Planner, WallWithGap)
{
  // Vertical wall at x = 5 with a one-cell gap at y = 8; start and goal on either side at y = 1.
  std::vector<std::string> rows(10, std::string(11, '.'));
  for (int y = 0; y < 10; ++y)
  {
    if (y != 8)
    {
      rows[y][5] = '#';
    }
  }
  const PlanningGrid g = fromText(rows);
  // Without corner cutting the gap (5, 8) is entered only from (4, 8) and left only to (6, 8):
  // (1,1) -> (4,8) = 3 sqrt2 + 4, then 2 through the gap, then (6,8) -> (9,1) = 3 sqrt2 + 4.
  EXPECT_NEAR(planBoth(g, Cell{ 1, 1 }, Cell{ 9, 1 }), 6.0 * kSqrt2 + 10.0, 1e-9);
}

TEST(Planner, NoCornerCutting)
{
  // Two diagonal blocked cells: the diagonal move between the two free cells is forbidden.
  const PlanningGrid g = fromText({ "..#", ".#.", "..." });
  EXPECT_EQ(g.moveCost(1, 0, 2, 1), kInf);
  // (0,0) -> (2,2): every diagonal next to the centre block is forbidden, so the path is the
  // four orthogonal moves (0,0) (0,1) (0,2) (1,2) (2,2).
  EXPECT_NEAR(planBoth(g, Cell{ 0, 0 }, Cell{ 2, 2 }), 4.0, kTol);
  // Blocked diagonal pair: cells (1,0) and (0,1) blocked; (0,0) can't reach (1,1) directly.
  const PlanningGrid g2 = fromText({ ".#", "#." });
  EXPECT_EQ(planBoth(g2, Cell{ 0, 0 }, Cell{ 1, 1 }), kInf);
}

TEST(Planner, NoPathWhenEnclosed)
{
  const PlanningGrid g = fromText({ ".......", ".#####.", ".#...#.", ".#...#.", ".#####.", "......." });
  EXPECT_EQ(planBoth(g, Cell{ 0, 0 }, Cell{ 3, 2 }), kInf);
  EXPECT_EQ(planBoth(g, Cell{ 3, 3 }, Cell{ 6, 5 }), kInf);
  // Start or goal inside a wall.
  EXPECT_EQ(planBoth(g, Cell{ 1, 1 }, Cell{ 6, 5 }), kInf);
  EXPECT_THROW(aStar(g, Cell{ -1, 0 }, Cell{ 0, 0 }), std::out_of_range);
  EXPECT_THROW(DStarLite(g, Cell{ 0, 0 }, Cell{ 7, 0 }), std::out_of_range);
}

TEST(Planner, UnknownPolicy)
{
  // A straight corridor of unknown cells vs a free detour.
  const std::vector<std::string> rows = { "..?..", ".###.", "....." };
  PlanningGridConfig cfg;
  cfg.unknown_policy = UnknownPolicy::kFree;
  EXPECT_NEAR(planBoth(fromText(rows, cfg), Cell{ 0, 0 }, Cell{ 4, 0 }), 4.0, kTol);
  cfg.unknown_policy = UnknownPolicy::kCostly;
  cfg.unknown_cost_multiplier = 1.5;
  // Through the unknown cell two moves touch it, each costing (1 + 1.5) / 2: 2 + 2.5 = 4.5. The
  // detour down column 0, along row 2 and up column 4 costs 8.
  EXPECT_NEAR(planBoth(fromText(rows, cfg), Cell{ 0, 0 }, Cell{ 4, 0 }), 4.5, kTol);
  cfg.unknown_cost_multiplier = 10.0;
  // Through: 2 + 11 = 13; detour down column 0, row 2, up column 4: 2 + 4 + 2 = 8.
  EXPECT_NEAR(planBoth(fromText(rows, cfg), Cell{ 0, 0 }, Cell{ 4, 0 }), 8.0, kTol);
  cfg.unknown_policy = UnknownPolicy::kBlocked;
  EXPECT_NEAR(planBoth(fromText(rows, cfg), Cell{ 0, 0 }, Cell{ 4, 0 }), 8.0, kTol);
  EXPECT_EQ(planBoth(fromText({ "..?.." }, cfg), Cell{ 0, 0 }, Cell{ 4, 0 }), kInf);
}

TEST(Planner, Inflation)
{
  // A 2-cell gap in a wall: open with radius 0, closed with radius 1 (both gap cells touch the wall).
  std::vector<std::string> rows(9, std::string(9, '.'));
  for (int x = 0; x < 9; ++x)
  {
    if (x != 4 && x != 5)
    {
      rows[4][x] = '#';
    }
  }
  PlanningGridConfig cfg;
  EXPECT_NEAR(planBoth(fromText(rows, cfg), Cell{ 4, 0 }, Cell{ 4, 8 }), 8.0, kTol);
  cfg.inflation_radius_cells = 1.0;
  const PlanningGrid inflated = fromText(rows, cfg);
  EXPECT_TRUE(inflated.traversable(4, 3));  // its nearest wall cell (3, 4) is sqrt2 away
  EXPECT_FALSE(inflated.traversable(4, 4));
  EXPECT_EQ(planBoth(inflated, Cell{ 4, 0 }, Cell{ 4, 8 }), kInf);
  // A 3-cell gap stays open with radius 1 through its middle cell.
  rows[4][6] = '.';
  const PlanningGrid wide = fromText(rows, cfg);
  EXPECT_TRUE(wide.traversable(5, 4));
  EXPECT_NEAR(planBoth(wide, Cell{ 5, 0 }, Cell{ 5, 8 }), 8.0, kTol);
  // Removing a wall cell clears its inflation incrementally.
  PlanningGrid g = fromText({ ".....", ".....", "..#..", ".....", "....." }, cfg);
  EXPECT_FALSE(g.traversable(1, 2));
  EXPECT_TRUE(g.traversable(1, 1));
  const auto changed = g.setStates({ { Cell{ 2, 2 }, CellState::kFree } });
  EXPECT_EQ(changed.size(), 5u);
  EXPECT_TRUE(g.traversable(1, 2));
}

TEST(Planner, FromOccupancy)
{
  OccupancyGrid og;
  og.width = 3;
  og.height = 2;
  og.data = { 0, 100, -1, 49, 50, 0 };
  PlanningGridConfig cfg;
  cfg.unknown_policy = UnknownPolicy::kBlocked;
  const PlanningGrid g = PlanningGrid::fromOccupancy(og, cfg);
  EXPECT_EQ(g.state(0, 0), CellState::kFree);
  EXPECT_EQ(g.state(1, 0), CellState::kBlocked);
  EXPECT_EQ(g.state(2, 0), CellState::kUnknown);
  EXPECT_EQ(g.state(0, 1), CellState::kFree);
  EXPECT_EQ(g.state(1, 1), CellState::kBlocked);
  EXPECT_FALSE(g.traversable(2, 0));
}

TEST(DStarLite, MatchesAStarAfterRandomChanges)
{
  std::mt19937 rng(12345);
  const int w = 40, h = 30;
  PlanningGridConfig cfg;
  cfg.unknown_policy = UnknownPolicy::kCostly;
  cfg.unknown_cost_multiplier = 3.0;
  PlanningGrid g(w, h, CellState::kFree, cfg);
  std::uniform_int_distribution<int> ux(0, w - 1), uy(0, h - 1), ustate(0, 9);
  std::vector<CellChange> init;
  for (int i = 0; i < 200; ++i)
  {
    init.push_back({ Cell{ ux(rng), uy(rng) }, CellState::kBlocked });
  }
  g.setStates(init);
  const Cell start{ 2, 2 }, goal{ w - 3, h - 3 };
  // Keep the 3 x 3 blocks around the start and the goal free so that most layouts have a path.
  auto nearEnd = [&](const Cell& c) {
    return (std::abs(c.x - start.x) <= 1 && std::abs(c.y - start.y) <= 1) ||
           (std::abs(c.x - goal.x) <= 1 && std::abs(c.y - goal.y) <= 1);
  };
  std::vector<CellChange> clear;
  for (int dy = -1; dy <= 1; ++dy)
  {
    for (int dx = -1; dx <= 1; ++dx)
    {
      clear.push_back({ Cell{ start.x + dx, start.y + dy }, CellState::kFree });
      clear.push_back({ Cell{ goal.x + dx, goal.y + dy }, CellState::kFree });
    }
  }
  g.setStates(clear);
  DStarLite d(g, start, goal);
  d.plan();
  PlanningGrid ref = g;
  int found = 0;
  for (int step = 0; step < 300; ++step)
  {
    std::vector<CellChange> batch;
    const int k = 1 + step % 3;
    for (int i = 0; i < k; ++i)
    {
      const int s = ustate(rng);
      const CellState st = s < 3 ? CellState::kBlocked : (s < 8 ? CellState::kFree : CellState::kUnknown);
      const Cell c{ ux(rng), uy(rng) };
      if (!nearEnd(c))
      {
        batch.push_back({ c, st });
      }
    }
    d.updateCells(batch);
    ref.setStates(batch);
    d.plan();
    const PlanResult a = aStar(ref, start, goal);
    ASSERT_EQ(a.found(), d.cost() < kInf) << "step " << step;
    if (a.found())
    {
      ++found;
      ASSERT_NEAR(d.cost(), a.cost, kTol * a.cost) << "step " << step;
      expectValidPath(ref, d.path(), start, goal, d.cost());
    }
  }
  EXPECT_GT(found, 150);
}

TEST(DStarLite, MoveStartConsistency)
{
  std::mt19937 rng(7);
  const int w = 35, h = 35;
  PlanningGrid g(w, h);
  std::uniform_int_distribution<int> ux(0, w - 1), uy(0, h - 1);
  std::vector<CellChange> init;
  for (int i = 0; i < 200; ++i)
  {
    init.push_back({ Cell{ ux(rng), uy(rng) }, CellState::kBlocked });
  }
  g.setStates(init);
  Cell start{ 1, 1 };
  const Cell goal{ w - 2, h - 2 };
  g.setStates({ { start, CellState::kFree }, { goal, CellState::kFree } });
  DStarLite d(g, start, goal);
  ASSERT_TRUE(d.plan());
  PlanningGrid ref = g;
  int moves = 0;
  while (start != goal && moves < 500)
  {
    const std::vector<Cell> p = d.path();
    ASSERT_GE(p.size(), 2u);
    start = p[1];
    d.moveStart(start);
    // Every other move, block a random cell other than the robot's and the goal's.
    if (moves % 2 == 0)
    {
      Cell c{ ux(rng), uy(rng) };
      if (c != start && c != goal)
      {
        d.updateCells({ { c, CellState::kBlocked } });
        ref.setStates({ { c, CellState::kBlocked } });
      }
    }
    EXPECT_THROW(d.path(), std::logic_error);
    const bool ok = d.plan();
    const PlanResult a = aStar(ref, start, goal);
    ASSERT_EQ(ok, a.found());
    if (!ok)
    {
      break;
    }
    ASSERT_NEAR(d.cost(), a.cost, kTol * std::max(1.0, a.cost));
    expectValidPath(ref, d.path(), start, goal, d.cost());
    ++moves;
  }
  EXPECT_GT(moves, 5);
}

TEST(Smoothing, StringPullAvoidsObstacles)
{
  const PlanningGrid g = fromText({ "..........", "..........", "....##....", "....##....", ".........." });
  const PlanResult a = aStar(g, Cell{ 0, 3 }, Cell{ 9, 3 });
  ASSERT_TRUE(a.found());
  const std::vector<Cell> s = smoothPath(g, a.path);
  ASSERT_GE(s.size(), 2u);
  EXPECT_LT(s.size(), a.path.size());
  EXPECT_EQ(s.front(), a.path.front());
  EXPECT_EQ(s.back(), a.path.back());
  for (std::size_t i = 1; i < s.size(); ++i)
  {
    EXPECT_TRUE(lineOfSight(g, s[i - 1], s[i]));
  }
  // Open grid: one straight segment.
  const PlanningGrid open(10, 10);
  const PlanResult b = aStar(open, Cell{ 0, 0 }, Cell{ 9, 4 });
  EXPECT_EQ(smoothPath(open, b.path).size(), 2u);
}

TEST(Smoothing, LineOfSightNoCornerCutting)
{
  // The segment (0,0) -> (2,2) passes exactly through the corner shared by (0,0), (1,0), (0,1), (1,1).
  const PlanningGrid g = fromText({ ".#.", "...", "..." });
  EXPECT_FALSE(lineOfSight(g, Cell{ 0, 0 }, Cell{ 2, 2 }));
  EXPECT_TRUE(lineOfSight(g, Cell{ 0, 1 }, Cell{ 2, 1 }));
  const PlanningGrid g2 = fromText({ "...", ".#.", "..." });
  EXPECT_FALSE(lineOfSight(g2, Cell{ 0, 0 }, Cell{ 2, 2 }));
  EXPECT_TRUE(lineOfSight(g2, Cell{ 0, 0 }, Cell{ 2, 0 }));
  // A shallow segment grazing a blocked cell it crosses.
  const PlanningGrid g3 = fromText({ ".....", "...#.", "....." });
  EXPECT_FALSE(lineOfSight(g3, Cell{ 0, 0 }, Cell{ 4, 2 }));
}
