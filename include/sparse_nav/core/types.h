#ifndef SPARSE_NAV_CORE_TYPES_H
#define SPARSE_NAV_CORE_TYPES_H

#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace sparse_nav
{
/// @brief A list of 3D points in metres; the frame is stated by whoever passes it.
using PointList = std::vector<Eigen::Vector3f>;

/// @brief A list of 2D points in metres in the map frame's x-y plane.
using PointList2D = std::vector<Eigen::Vector2d>;

/**
 * @brief A 2D occupancy grid with nav_msgs/OccupancyGrid conventions, ROS-free.
 *
 * Cell (col, row) covers x in [origin_x_m + col * resolution_m, origin_x_m + (col + 1) * resolution_m)
 * and likewise for y; data is row-major with row 0 at the lowest y (the same as OccupancyGrid).
 * Values: kOccupied (100), kFree (0), kUnknown (-1).
 */
struct OccupancyGrid
{
  static constexpr std::int8_t kFree = 0;
  static constexpr std::int8_t kOccupied = 100;
  static constexpr std::int8_t kUnknown = -1;

  double resolution_m = 0.05;  ///< edge length of a cell [m]
  double origin_x_m = 0.0;     ///< x of the lower-left corner of cell (0, 0) in the map frame [m]
  double origin_y_m = 0.0;     ///< y of the lower-left corner of cell (0, 0) in the map frame [m]
  int width = 0;               ///< number of columns (along x)
  int height = 0;              ///< number of rows (along y)
  std::vector<std::int8_t> data;  ///< row-major, width * height values

  /// @brief True when the grid has no cells.
  bool empty() const { return width <= 0 || height <= 0; }
  /// @brief Value of cell (col, row); the caller keeps the indices in range.
  std::int8_t at(int col, int row) const { return data[static_cast<std::size_t>(row) * width + col]; }
  /// @brief Column of the cell containing map x [m] (may be outside [0, width)).
  int colOf(double x_m) const;
  /// @brief Row of the cell containing map y [m] (may be outside [0, height)).
  int rowOf(double y_m) const;
  /// @brief Number of cells holding the given value.
  std::size_t count(std::int8_t value) const;
};

/// @brief Index of a tile of the grid (tx along x, ty along y), in tiles.
struct TileIndex
{
  int tx = 0;
  int ty = 0;
  bool operator==(const TileIndex& o) const { return tx == o.tx && ty == o.ty; }
  bool operator<(const TileIndex& o) const { return ty < o.ty || (ty == o.ty && tx < o.tx); }
};

}  // namespace sparse_nav

#endif  // SPARSE_NAV_CORE_TYPES_H
