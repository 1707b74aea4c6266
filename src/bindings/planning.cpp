// pybind11 module sparse_nav._planning: the grid planners of sparse_nav_core for Python.
// Cells are (x, y) tuples with x the column and y the row; arrays are indexed [y, x].
// Cell values follow nav_msgs/OccupancyGrid: negative = unknown, >= occupied_threshold = blocked,
// anything else free; uint8 arrays read 255 as unknown.
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "sparse_nav/core/grid_planner.h"

namespace py = pybind11;
using sparse_nav::Cell;
using sparse_nav::CellChange;
using sparse_nav::CellState;
using sparse_nav::DStarLite;
using sparse_nav::PlanningGrid;
using sparse_nav::PlanningGridConfig;
using sparse_nav::UnknownPolicy;

namespace
{
using PyCell = std::pair<int, int>;

Cell toCell(const PyCell& c)
{
  return Cell{ c.first, c.second };
}

std::vector<PyCell> toPy(const std::vector<Cell>& path)
{
  std::vector<PyCell> out;
  out.reserve(path.size());
  for (const auto& c : path)
  {
    out.emplace_back(c.x, c.y);
  }
  return out;
}

std::vector<Cell> fromPy(const std::vector<PyCell>& path)
{
  std::vector<Cell> out;
  out.reserve(path.size());
  for (const auto& c : path)
  {
    out.push_back(toCell(c));
  }
  return out;
}

CellState stateOf(int value, int threshold)
{
  if (value < 0)
  {
    return CellState::kUnknown;
  }
  return value >= threshold ? CellState::kBlocked : CellState::kFree;
}

UnknownPolicy policyOf(const std::string& name)
{
  if (name == "free")
  {
    return UnknownPolicy::kFree;
  }
  if (name == "costly")
  {
    return UnknownPolicy::kCostly;
  }
  if (name == "blocked")
  {
    return UnknownPolicy::kBlocked;
  }
  throw std::invalid_argument("unknown_policy must be 'free', 'costly' or 'blocked', got '" + name + "'");
}

std::string policyName(UnknownPolicy p)
{
  switch (p)
  {
    case UnknownPolicy::kFree:
      return "free";
    case UnknownPolicy::kCostly:
      return "costly";
    case UnknownPolicy::kBlocked:
      return "blocked";
  }
  return "costly";
}

PlanningGrid gridFromArray(const py::array& array, const std::string& unknown_policy, double unknown_cost,
                           double inflation_radius, int occupied_threshold)
{
  PlanningGridConfig cfg;
  cfg.unknown_policy = policyOf(unknown_policy);
  cfg.unknown_cost_multiplier = unknown_cost;
  cfg.inflation_radius_cells = inflation_radius;
  cfg.occupied_threshold = occupied_threshold;
  cfg.validate();
  if (array.ndim() != 2)
  {
    throw std::invalid_argument("Grid: expected a 2D array indexed [y, x]");
  }
  const bool is_int8 = py::isinstance<py::array_t<std::int8_t>>(array);
  const bool is_uint8 = py::isinstance<py::array_t<std::uint8_t>>(array);
  if (!is_int8 && !is_uint8)
  {
    throw std::invalid_argument("Grid: expected an int8 or uint8 array");
  }
  const int h = static_cast<int>(array.shape(0)), w = static_cast<int>(array.shape(1));
  PlanningGrid grid(w, h, CellState::kFree, cfg);
  std::vector<CellChange> changes;
  if (is_int8)
  {
    const auto a = py::array_t<std::int8_t>::ensure(array).unchecked<2>();
    for (int y = 0; y < h; ++y)
    {
      for (int x = 0; x < w; ++x)
      {
        const CellState s = stateOf(a(y, x), occupied_threshold);
        if (s != CellState::kFree)
        {
          changes.push_back({ Cell{ x, y }, s });
        }
      }
    }
  }
  else
  {
    const auto a = py::array_t<std::uint8_t>::ensure(array).unchecked<2>();
    for (int y = 0; y < h; ++y)
    {
      for (int x = 0; x < w; ++x)
      {
        const int v = a(y, x) == 255 ? -1 : a(y, x);
        const CellState s = stateOf(v, occupied_threshold);
        if (s != CellState::kFree)
        {
          changes.push_back({ Cell{ x, y }, s });
        }
      }
    }
  }
  grid.setStates(changes);
  return grid;
}

std::vector<CellChange> changesOf(const PlanningGrid& grid, const std::vector<std::tuple<int, int, int>>& cells)
{
  std::vector<CellChange> out;
  out.reserve(cells.size());
  for (const auto& c : cells)
  {
    out.push_back({ Cell{ std::get<0>(c), std::get<1>(c) },
                    stateOf(std::get<2>(c), grid.config().occupied_threshold) });
  }
  return out;
}

py::array_t<std::int8_t> statesArray(const PlanningGrid& g)
{
  py::array_t<std::int8_t> out({ g.height(), g.width() });
  auto a = out.mutable_unchecked<2>();
  for (int y = 0; y < g.height(); ++y)
  {
    for (int x = 0; x < g.width(); ++x)
    {
      const CellState s = g.state(x, y);
      a(y, x) = s == CellState::kBlocked ? 100 : (s == CellState::kUnknown ? -1 : 0);
    }
  }
  return out;
}

py::array_t<bool> traversableArray(const PlanningGrid& g)
{
  py::array_t<bool> out({ g.height(), g.width() });
  auto a = out.mutable_unchecked<2>();
  for (int y = 0; y < g.height(); ++y)
  {
    for (int x = 0; x < g.width(); ++x)
    {
      a(y, x) = g.traversable(x, y);
    }
  }
  return out;
}
}  // namespace

PYBIND11_MODULE(_planning, m)
{
  m.doc() = "Grid planners of sparse_nav_core: D* Lite, A* and line-of-sight smoothing (cells are (x, y)).";

  py::class_<PlanningGrid>(m, "Grid")
      .def(py::init(&gridFromArray), py::arg("array"), py::arg("unknown_policy") = "costly",
           py::arg("unknown_cost") = PlanningGridConfig().unknown_cost_multiplier,
           py::arg("inflation_radius") = PlanningGridConfig().inflation_radius_cells,
           py::arg("occupied_threshold") = PlanningGridConfig().occupied_threshold,
           "Grid from a 2D int8/uint8 array [y, x] of OccupancyGrid values (negative or 255 = unknown).")
      .def_property_readonly("width", &PlanningGrid::width)
      .def_property_readonly("height", &PlanningGrid::height)
      .def_property_readonly("unknown_policy", [](const PlanningGrid& g) { return policyName(g.config().unknown_policy); })
      .def("traversable", &PlanningGrid::traversable, py::arg("x"), py::arg("y"))
      .def(
          "move_cost",
          [](const PlanningGrid& g, const PyCell& a, const PyCell& b) {
            if (!g.inBounds(a.first, a.second) || !g.inBounds(b.first, b.second) ||
                std::abs(a.first - b.first) > 1 || std::abs(a.second - b.second) > 1)
            {
              throw std::invalid_argument("move_cost: cells must be in bounds and 8-neighbours");
            }
            return g.moveCost(a.first, a.second, b.first, b.second);
          },
          py::arg("a"), py::arg("b"))
      .def(
          "update_cells",
          [](PlanningGrid& g, const std::vector<std::tuple<int, int, int>>& cells) {
            g.setStates(changesOf(g, cells));
          },
          py::arg("cells"), "Sets cells from (x, y, value) tuples with OccupancyGrid values.")
      .def("states", &statesArray, "Cell states as an int8 array [y, x]: 0 free, 100 blocked, -1 unknown.")
      .def("traversable_mask", &traversableArray,
           "Traversability (after the unknown policy and inflation) as a bool array [y, x].");

  py::class_<DStarLite>(m, "DStarLite")
      .def(py::init([](const PlanningGrid& g, const PyCell& start, const PyCell& goal) {
             return DStarLite(g, toCell(start), toCell(goal));
           }),
           py::arg("grid"), py::arg("start"), py::arg("goal"))
      .def("plan", &DStarLite::plan, py::call_guard<py::gil_scoped_release>(),
           "Repairs the search; True when a path exists.")
      .def(
          "update_cells",
          [](DStarLite& d, const std::vector<std::tuple<int, int, int>>& cells) {
            d.updateCells(changesOf(d.grid(), cells));
          },
          py::arg("cells"), "Applies (x, y, value) changes with OccupancyGrid values; call plan() after.")
      .def(
          "move_start", [](DStarLite& d, const PyCell& s) { d.moveStart(toCell(s)); }, py::arg("start"))
      .def("path", [](const DStarLite& d) { return toPy(d.path()); })
      .def("cost", &DStarLite::cost)
      .def_property_readonly("start", [](const DStarLite& d) { return PyCell(d.start().x, d.start().y); })
      .def_property_readonly("goal", [](const DStarLite& d) { return PyCell(d.goal().x, d.goal().y); })
      .def_property_readonly("expansions", &DStarLite::expansions)
      .def_property_readonly("grid", [](const DStarLite& d) { return d.grid(); });

  m.def(
      "astar",
      [](const PlanningGrid& g, const PyCell& start, const PyCell& goal) {
        sparse_nav::PlanResult r;
        {
          py::gil_scoped_release release;
          r = sparse_nav::aStar(g, toCell(start), toCell(goal));
        }
        return std::make_pair(toPy(r.path), r.cost);
      },
      py::arg("grid"), py::arg("start"), py::arg("goal"), "A* reference: (path, cost); ([], inf) when none.");
  m.def(
      "smooth", [](const PlanningGrid& g, const std::vector<PyCell>& path) { return toPy(sparse_nav::smoothPath(g, fromPy(path))); },
      py::arg("grid"), py::arg("path"), "Line-of-sight (string-pull) smoothing of a path.");
  m.def(
      "line_of_sight",
      [](const PlanningGrid& g, const PyCell& a, const PyCell& b) { return sparse_nav::lineOfSight(g, toCell(a), toCell(b)); },
      py::arg("grid"), py::arg("a"), py::arg("b"));
}
