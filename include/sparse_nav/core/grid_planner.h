#ifndef SPARSE_NAV_CORE_GRID_PLANNER_H
#define SPARSE_NAV_CORE_GRID_PLANNER_H

#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "sparse_nav/core/types.h"

namespace sparse_nav
{
/// @brief A cell of a planning grid: x is the column, y the row (both in cells).
struct Cell
{
  int x = 0;
  int y = 0;
  bool operator==(const Cell& o) const { return x == o.x && y == o.y; }
  bool operator!=(const Cell& o) const { return !(*this == o); }
};

/// @brief What a planning cell holds before the unknown policy and inflation are applied.
enum class CellState : std::uint8_t
{
  kFree = 0,
  kBlocked = 1,
  kUnknown = 2
};

/// @brief How unknown cells are treated by the planners.
enum class UnknownPolicy : std::uint8_t
{
  kFree = 0,    ///< traversed like free cells
  kCostly = 1,  ///< traversable, each move touching them costs unknown_cost_multiplier times more
  kBlocked = 2  ///< not traversable (they are not inflated)
};

/// @brief Configuration of PlanningGrid.
struct PlanningGridConfig
{
  UnknownPolicy unknown_policy = UnknownPolicy::kCostly;
  /// Multiplier (>= 1) on the cost of a move into or out of an unknown cell under kCostly; a move
  /// costs its length times the mean of the multipliers of its two cells (free cells count 1).
  double unknown_cost_multiplier = 2.0;
  /// Robot radius [cells]: every cell whose centre is within this distance of a blocked cell's
  /// centre is not traversable. 0 disables inflation.
  double inflation_radius_cells = 0.0;
  /// OccupancyGrid values >= this are blocked (fromOccupancy only); negative values are unknown.
  int occupied_threshold = 50;

  /// @brief Throws std::invalid_argument when a value is out of range.
  void validate() const;
};

/// @brief A change of one cell's state.
struct CellChange
{
  Cell cell;
  CellState state = CellState::kFree;
};

/**
 * @brief The grid both planners search: 8-connected, moves of length 1 (orthogonal) and sqrt(2)
 * (diagonal), no corner cutting (a diagonal move needs both side cells traversable).
 *
 * Each cell has a state; its cost multiplier follows from the unknown policy and the inflation
 * (infinity when not traversable). A move between traversable cells a and b costs
 * length * (m(a) + m(b)) / 2, so costs are symmetric and never below the octile distance.
 */
class PlanningGrid
{
public:
  PlanningGrid() = default;
  /// @brief A width x height grid with every cell in state fill.
  PlanningGrid(int width, int height, CellState fill = CellState::kFree,
               const PlanningGridConfig& config = PlanningGridConfig());
  /// @brief A grid from an OccupancyGrid (column = x, row = y), using config.occupied_threshold.
  static PlanningGrid fromOccupancy(const OccupancyGrid& grid,
                                    const PlanningGridConfig& config = PlanningGridConfig());

  int width() const { return width_; }
  int height() const { return height_; }
  const PlanningGridConfig& config() const { return config_; }
  bool inBounds(int x, int y) const { return x >= 0 && y >= 0 && x < width_ && y < height_; }
  std::size_t index(int x, int y) const { return static_cast<std::size_t>(y) * width_ + x; }

  /// @brief State of cell (x, y); the caller keeps it in bounds.
  CellState state(int x, int y) const { return states_[index(x, y)]; }
  /// @brief Cost multiplier of cell (x, y): 1 free, >= 1 unknown, infinity when not traversable.
  double multiplier(int x, int y) const { return mult_[index(x, y)]; }
  /// @brief True when cell (x, y) is in bounds and can be entered.
  bool traversable(int x, int y) const
  {
    return inBounds(x, y) && mult_[index(x, y)] < std::numeric_limits<double>::infinity();
  }
  /// @brief Cost of the move from a to the 8-neighbour b; infinity when not allowed.
  double moveCost(int ax, int ay, int bx, int by) const;

  /**
   * @brief Applies state changes (out-of-bounds cells throw std::out_of_range).
   * @return flat indices of the cells whose multiplier changed, each once.
   */
  std::vector<std::size_t> setStates(const std::vector<CellChange>& changes);

private:
  void recompute(std::size_t i);

  PlanningGridConfig config_;
  int width_ = 0;
  int height_ = 0;
  std::vector<CellState> states_;
  std::vector<std::int32_t> blocked_near_;  ///< blocked cells within the inflation radius (self included)
  std::vector<double> mult_;
  std::vector<std::pair<int, int>> disk_;   ///< inflation offsets
  std::vector<std::uint8_t> mark_;          ///< scratch for setStates
};

/// @brief Octile distance between two cells [cells]: the cost lower bound of both planners.
double octileDistance(const Cell& a, const Cell& b);

/// @brief A path as cells from start to goal and its cost; empty with infinite cost when none exists.
struct PlanResult
{
  std::vector<Cell> path;
  double cost = std::numeric_limits<double>::infinity();
  std::size_t expansions = 0;  ///< cells expanded by the search
  bool found() const { return !path.empty(); }
};

/// @brief A* with the octile heuristic on the same moves and costs as DStarLite (the reference).
PlanResult aStar(const PlanningGrid& grid, const Cell& start, const Cell& goal);

/**
 * @brief Optimised D* Lite (Koenig & Likhachev 2002, with the key modifier k_m) searching from the
 * goal toward the start, so cost changes and start moves are repaired incrementally.
 */
class DStarLite
{
public:
  /// @brief Takes a copy of grid; start and goal out of bounds throw std::out_of_range.
  DStarLite(PlanningGrid grid, const Cell& start, const Cell& goal);

  /// @brief Repairs the search after changes. @return true when a path exists.
  bool plan();
  /// @brief Applies cell changes to the grid and marks the affected cells; call plan() afterwards.
  void updateCells(const std::vector<CellChange>& changes);
  /// @brief Moves the start (the robot) to a new cell; call plan() afterwards.
  void moveStart(const Cell& start);
  /// @brief Greedy path over cost + g from the start to the goal; empty when none exists.
  /// Throws std::logic_error when plan() was not called since the last change.
  std::vector<Cell> path() const;
  /// @brief Cost of the shortest path from the start (infinity when none). Throws like path().
  double cost() const;

  const PlanningGrid& grid() const { return grid_; }
  const Cell& start() const { return start_; }
  const Cell& goal() const { return goal_; }
  /// @brief Cells expanded by the last plan().
  std::size_t expansions() const { return expansions_; }

private:
  struct Key
  {
    double k1;
    double k2;
    bool operator<(const Key& o) const { return k1 < o.k1 || (k1 == o.k1 && k2 < o.k2); }
  };

  Key calculateKey(std::size_t s) const;
  void updateVertex(std::size_t s);
  double bestRhs(std::size_t s) const;
  double heuristic(std::size_t s) const;
  void requirePlanned() const;

  // Indexed binary min-heap with decrease/increase-key and removal.
  void heapPush(std::size_t s, const Key& k);
  void heapUpdate(std::size_t s, const Key& k);
  void heapRemove(std::size_t s);
  void siftUp(std::size_t pos);
  void siftDown(std::size_t pos);
  void heapSwap(std::size_t a, std::size_t b);
  bool inHeap(std::size_t s) const { return heap_pos_[s] >= 0; }

  PlanningGrid grid_;
  Cell start_;
  Cell goal_;
  Cell last_;
  double k_m_ = 0.0;
  std::vector<double> g_;
  std::vector<double> rhs_;
  std::vector<std::pair<Key, std::uint32_t>> heap_;
  std::vector<std::int32_t> heap_pos_;
  std::size_t expansions_ = 0;
  bool planned_ = false;
};

/**
 * @brief Line-of-sight (string-pull) smoothing: keeps the path's first and last cells and drops
 * every waypoint that the previous kept one sees directly. A straight segment is accepted only when
 * every cell it touches (supercover, both side cells where it passes exactly through a corner) is
 * traversable and no costlier than the costliest cell of the part of the path it replaces.
 */
std::vector<Cell> smoothPath(const PlanningGrid& grid, const std::vector<Cell>& path);

/// @brief True when the segment between the centres of a and b touches only cells whose multiplier
/// is at most max_multiplier (supercover; both side cells are checked at exact corner crossings).
bool lineOfSight(const PlanningGrid& grid, const Cell& a, const Cell& b,
                 double max_multiplier = std::numeric_limits<double>::max());

}  // namespace sparse_nav

#endif  // SPARSE_NAV_CORE_GRID_PLANNER_H
