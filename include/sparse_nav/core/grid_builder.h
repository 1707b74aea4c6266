#ifndef SPARSE_NAV_CORE_GRID_BUILDER_H
#define SPARSE_NAV_CORE_GRID_BUILDER_H

#include <cstdint>
#include <functional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "sparse_nav/core/types.h"

namespace sparse_nav
{
/// @brief Configuration of the alpha shapes over the obstacle slice (map frame, metres).
struct AlphaShapeConfig
{
  /// Alpha as a radius [m] (CGAL's alpha is its square). Two obstacle points are joined when a
  /// circle of this radius touches both with no point inside, so gaps up to 2 * alpha_m close and
  /// wider ones (doorways) stay open. 0.17 m: a door seen obliquely from across the room shows
  /// only a band a few cells wide between its jambs' noisy points, which 0.2 m closed in one scan
  /// in five (bench/bench_grid_accuracy.py); walls lose about one point of recall.
  double alpha_m = 0.17;
  /// When true, alpha_m is replaced at each full rebuild by
  /// clamp(auto_alpha_factor * P(auto_alpha_percentile) of the nearest-neighbour spacing of the
  /// one-point-per-cell obstacles, [resolution, max_auto_alpha_m]); incremental updates keep it.
  bool auto_alpha = false;
  double auto_alpha_percentile = 90.0;  ///< percentile of nearest-neighbour spacing [0, 100]
  double auto_alpha_factor = 1.0;       ///< multiplier on that spacing
  double max_auto_alpha_m = 0.4;        ///< upper bound for the automatic alpha [m] (keeps 0.9 m doors open)

  /// @brief Throws std::invalid_argument when a value is out of range.
  void validate() const;
};

/// @brief Alpha-shape output in the map frame [m].
struct AlphaShapeResult
{
  std::vector<std::vector<Eigen::Vector2d>> rings;                 ///< closed rings of regular edges
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> segments;  ///< singular edges (no area)
  double alpha_m = 0.0;  ///< alpha radius used [m]
};

/**
 * @brief The alpha shape of CGAL's Alpha_shape_2 (GENERAL mode) over 2D points [m], classified for
 * this one alpha on a CGAL Delaunay triangulation: regular edges chained into rings, singular edges
 * kept as segments. Points are used as given (GridBuilder passes one per cell).
 */
AlphaShapeResult computeAlphaShape(const PointList2D& points, double alpha_m);

/// @brief The automatic alpha rule of AlphaShapeConfig for these points [m].
double automaticAlpha(const PointList2D& points, const AlphaShapeConfig& config, double resolution_m);

/// @brief A 2D free-space ray in the map frame [m]: the part of a camera-to-point ray inside the slice band.
struct FreeRay
{
  Eigen::Vector2d from;
  Eigen::Vector2d to;
};

/// @brief Configuration of GridBuilder.
struct GridBuilderConfig
{
  double resolution_m = 0.05;  ///< cell edge [m]
  int tile_size_cells = 32;    ///< dirty-region tile edge [cells]
  double padding_m = 0.5;      ///< free margin around the data when the grid is sized [m]
  int max_cells = 100000000;   ///< refuse grids with more cells than this (huge extents; 5 bytes per cell)
  AlphaShapeConfig alpha;
  /// A cell of a singular alpha edge (two points joined with no area between them) that at least
  /// this many distinct free rays cross stays free: rays seen through a gap beat a line drawn
  /// across it. Ring edges and interiors stay occupied whatever crosses them (noisy wall bands
  /// are crossed by rays to their own far points). 0: never.
  int clear_segment_min_rays = 2;

  /// @brief Throws std::invalid_argument when a value is out of range.
  void validate() const;
};

/// @brief What changed between two clouds given to GridBuilder: obstacle points and free rays
/// that went and that came (map frame, metres). A point or ray present several times counts
/// several times.
struct GridChange
{
  PointList2D obstacles_removed;
  PointList2D obstacles_added;
  std::vector<FreeRay> rays_removed;
  std::vector<FreeRay> rays_added;
};

/// @brief What GridBuilder::update did.
struct GridUpdate
{
  bool ok = true;
  std::string status;             ///< human-readable summary or the reason for !ok
  bool full_rebuild = false;      ///< the whole grid was recomputed (first update, growth, alpha change)
  std::vector<TileIndex> recomputed_tiles;  ///< tiles rewritten
  std::vector<TileIndex> changed_tiles;     ///< rewritten tiles whose cells differ from before
  /// Bounding box of changed_tiles in cells [min_col, max_col) x [min_row, max_row); empty when none changed.
  int min_col = 0, min_row = 0, max_col = 0, max_row = 0;
  double alpha_m = 0.0;           ///< alpha radius used [m]
  std::size_t n_obstacle_cells = 0;
  std::size_t n_rays = 0;
};

/**
 * @brief Builds and incrementally updates an OccupancyGrid from obstacle points and free rays.
 *
 * Obstacles are reduced to one point per cell; CGAL alpha shapes over them are rasterised by
 * scanline fill (cv::fillPoly) and lines into occupied cells; free rays are rasterised (integer
 * Bresenham) into a per-cell count of the rays crossing it, and cells with a count are free; the
 * rest is unknown, and the cells of a singular alpha edge that rays cross are free
 * (clear_segment_min_rays). The grid is split in tiles; an update compares the obstacle cells per tile and
 * the set of rays with the previous update, subtracts the removed rays from the counts and adds the
 * new ones, and recomputes only tiles within reach of a change (alpha shapes reach 2 * alpha: one
 * tile of margin at the defaults), giving the same cells as a full rebuild. The grid only grows:
 * data outside it forces a rebuild.
 */
class GridBuilder
{
public:
  explicit GridBuilder(const GridBuilderConfig& config = GridBuilderConfig());

  /// @param obstacles obstacle points projected to the map x-y plane [m]
  /// @param rays free-space rays [m]; a caller done with them moves them in, and their memory
  ///        (as much as the grid's own) is given back before the grid's arrays are made
  GridUpdate update(const PointList2D& obstacles, std::vector<FreeRay> rays);
  /**
   * @brief update(obstacles, rays) for lists that differ from the last call's by `change`, looking
   * at the changed cells and rays alone instead of comparing the whole lists. Falls back to
   * update(obstacles, rays()) when the change reaches beyond the grid or does not follow from what
   * the last call gave (a removed point or ray it never held): rays() gives the whole list of rays,
   * asked for only then.
   */
  GridUpdate update(const PointList2D& obstacles, const std::function<std::vector<FreeRay>()>& rays, const GridChange& change);
  /// @brief Forgets everything; the next update is a full rebuild.
  void reset();

  const OccupancyGrid& grid() const { return grid_; }
  /// @brief Alpha shape computed by the last full rebuild (map frame, metres).
  const AlphaShapeResult& lastShape() const { return last_shape_; }
  const GridBuilderConfig& config() const { return config_; }

  struct Ray
  {
    std::int32_t x0, y0, x1, y1;  // absolute cells, canonical order
    bool operator<(const Ray& o) const { return std::tie(x0, y0, x1, y1) < std::tie(o.x0, o.y0, o.x1, o.y1); }
    bool operator==(const Ray& o) const { return x0 == o.x0 && y0 == o.y0 && x1 == o.x1 && y1 == o.y1; }
  };

private:
  struct Window
  {
    int col0, row0, cols, rows;  // in grid cells
  };
  void recomputeWindow(const Window& window, const std::vector<std::uint8_t>& write_tile, double alpha_m,
                       bool keep_shape);
  /// Tiles of context an alpha shape needs around a tile (2 * alpha, and a cell of rounding).
  int marginTiles() const;
  /// Marks for writing every tile within marginTiles() of a dirty one.
  void markAroundDirty(const std::vector<std::uint8_t>& dirty, std::vector<std::uint8_t>& write) const;
  /// Recomputes the tiles marked in write and fills in result's tiles and status.
  GridUpdate finish(const std::vector<std::uint8_t>& write, bool full, GridUpdate result);
  /// The absolute cell of p; false when a coordinate is not finite or too large.
  bool toCell(const Eigen::Vector2d& p, std::int64_t& x, std::int64_t& y) const;
  /// The ray's end cells, in canonical order; false when a coordinate is not finite or too large.
  bool toRay(const FreeRay& r, Ray& out) const;

  GridBuilderConfig config_;
  OccupancyGrid grid_;
  std::int64_t cell0_x_ = 0;  // absolute cell index of grid column 0
  std::int64_t cell0_y_ = 0;
  int tiles_x_ = 0, tiles_y_ = 0;
  double alpha_m_ = 0.0;
  std::vector<std::vector<std::uint32_t>> tile_cells_;  // sorted local cell ids per tile
  std::vector<Ray> rays_;                                // sorted, unique
  std::vector<std::uint32_t> ray_count_;                 // per rays_ entry: its copies among the last rays
  std::vector<std::uint32_t> ray_cover_;                 // per grid cell: how many of rays_ cross it
  std::vector<std::uint32_t> obstacle_count_;            // per grid cell: the last obstacle points in it
  AlphaShapeResult last_shape_;
};

}  // namespace sparse_nav

#endif  // SPARSE_NAV_CORE_GRID_BUILDER_H
