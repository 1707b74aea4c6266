#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <random>
#include <set>
#include <tuple>

#include <CGAL/Alpha_shape_2.h>
#include <CGAL/Alpha_shape_face_base_2.h>
#include <CGAL/Alpha_shape_vertex_base_2.h>
#include <CGAL/Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <stdexcept>

#include "sparse_nav/core/grid_builder.h"
#include "../../src/core/radix_sort.h"

using sparse_nav::FreeRay;
using sparse_nav::GridBuilder;
using sparse_nav::GridBuilderConfig;
using sparse_nav::GridUpdate;
using sparse_nav::OccupancyGrid;
using sparse_nav::PointList2D;

namespace
{
constexpr double kRes = 0.05;

/// Centre of absolute cell (i, j) at the default resolution.
Eigen::Vector2d cell(int i, int j)
{
  return Eigen::Vector2d((i + 0.5) * kRes, (j + 0.5) * kRes);
}

std::int8_t valueAt(const OccupancyGrid& g, double x, double y)
{
  const int c = g.colOf(x), r = g.rowOf(y);
  EXPECT_TRUE(c >= 0 && r >= 0 && c < g.width && r < g.height) << x << ", " << y;
  return g.at(c, r);
}

/// Outline of a 5 m x 4 m room as sparse 2D points (every 6 cells = 0.3 m), with a 0.9 m door in
/// the wall y = 0 between x = 1.0 and x = 1.9; rays from a camera at the centre to every point,
/// and one ray out through the door.
void sparseRoom(PointList2D& pts, std::vector<FreeRay>& rays)
{
  pts.clear();
  rays.clear();
  for (int i = 0; i <= 100; i += 6)
  {
    if (i * kRes < 1.0 - 1e-9 || i * kRes > 1.9 + 1e-9)
    {
      pts.push_back(cell(i, 0));
    }
    pts.push_back(cell(i, 80));
  }
  pts.push_back(cell(19, 0));  // door jambs at 0.95 m and 1.95 m: a 0.9 m opening
  pts.push_back(cell(39, 0));
  for (int j = 0; j <= 80; j += 6)
  {
    pts.push_back(cell(0, j));
    pts.push_back(cell(100, j));
  }
  const Eigen::Vector2d camera(2.5, 2.0);
  for (const auto& p : pts)
  {
    rays.push_back(FreeRay{ camera, p });
  }
  rays.push_back(FreeRay{ Eigen::Vector2d(1.45, 2.0), Eigen::Vector2d(1.45, -1.0) });
}
}  // namespace

TEST(AlphaShape, ClosesASparseWallButKeepsTheDoorwayOpen)
{
  PointList2D pts;
  std::vector<FreeRay> rays;
  sparseRoom(pts, rays);
  GridBuilderConfig cfg;
  cfg.alpha.alpha_m = 0.25;  // closes gaps up to 0.5 m
  GridBuilder builder(cfg);
  const GridUpdate u = builder.update(pts, rays);
  ASSERT_TRUE(u.ok) << u.status;
  const OccupancyGrid& g = builder.grid();
  // Between sparse wall points (0.3 m apart) the wall is closed.
  for (double x = 2.2; x < 4.8; x += kRes)
  {
    EXPECT_EQ(valueAt(g, x, 4.0 + 0.5 * kRes), OccupancyGrid::kOccupied) << "north wall at x " << x;
  }
  for (double y = 0.1; y < 3.9; y += kRes)
  {
    EXPECT_EQ(valueAt(g, 0.5 * kRes, y), OccupancyGrid::kOccupied) << "west wall at y " << y;
  }
  // The 0.9 m doorway stays open (free along the ray through it).
  for (double x = 1.05; x <= 1.85; x += kRes)
  {
    EXPECT_NE(valueAt(g, x, 0.5 * kRes), OccupancyGrid::kOccupied) << "door at x " << x;
  }
  EXPECT_EQ(valueAt(g, 1.45, 0.5 * kRes), OccupancyGrid::kFree);
  // Inside the room is free, behind the walls unknown.
  EXPECT_EQ(valueAt(g, 2.5, 2.0), OccupancyGrid::kFree);
  EXPECT_EQ(valueAt(g, 1.0, 3.0), OccupancyGrid::kFree);
  EXPECT_EQ(valueAt(g, 3.0, 4.3), OccupancyGrid::kUnknown);
  EXPECT_NEAR(u.alpha_m, 0.25, 1e-12);
}

TEST(AlphaShape, AutomaticAlphaFollowsTheSpacingAndKeepsTheDoorOpen)
{
  PointList2D pts;
  std::vector<FreeRay> rays;
  sparseRoom(pts, rays);
  GridBuilderConfig cfg;
  cfg.alpha.auto_alpha = true;
  GridBuilder builder(cfg);
  const GridUpdate u = builder.update(pts, rays);
  ASSERT_TRUE(u.ok);
  EXPECT_GE(u.alpha_m, 0.15);  // half the 0.3 m spacing or more closes the wall
  EXPECT_LE(u.alpha_m, 0.4);
  EXPECT_NE(valueAt(builder.grid(), 1.45, 0.5 * kRes), OccupancyGrid::kOccupied);
  EXPECT_EQ(valueAt(builder.grid(), 3.0, 4.0 + 0.5 * kRes), OccupancyGrid::kOccupied);
}

TEST(AlphaShape, RingsAndSegments)
{
  // Four points of a 1 m square, alpha 1 m: one ring of four edges.
  const PointList2D square{ { 0, 0 }, { 1, 0 }, { 1, 1 }, { 0, 1 } };
  const auto filled = sparse_nav::computeAlphaShape(square, 1.0);
  ASSERT_EQ(filled.rings.size(), 1u);
  EXPECT_EQ(filled.rings[0].size(), 4u);
  EXPECT_TRUE(filled.segments.empty());
  // alpha 0.6 m: the sides (0.5 m half-length) are singular edges, the square is not filled.
  const auto outline = sparse_nav::computeAlphaShape(square, 0.6);
  EXPECT_TRUE(outline.rings.empty());
  EXPECT_EQ(outline.segments.size(), 4u);
  // Collinear points (a 1-D triangulation) still give segments.
  const auto line = sparse_nav::computeAlphaShape(PointList2D{ { 0, 0 }, { 0.2, 0 }, { 0.4, 0 }, { 2.0, 0 } }, 0.15);
  EXPECT_EQ(line.segments.size(), 2u);
}

namespace
{
using Edge2 = std::tuple<double, double, double, double>;

/// Regular edges (interior on the left) and singular edges (sorted ends) of CGAL's own
/// Alpha_shape_2 in GENERAL mode: the reference computeAlphaShape must reproduce.
std::pair<std::set<Edge2>, std::set<Edge2>> cgalAlphaShape(const PointList2D& points, double alpha_m)
{
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;
  using Tds = CGAL::Triangulation_data_structure_2<CGAL::Alpha_shape_vertex_base_2<K>, CGAL::Alpha_shape_face_base_2<K>>;
  using Shape = CGAL::Alpha_shape_2<CGAL::Delaunay_triangulation_2<K, Tds>>;
  std::vector<K::Point_2> pts;
  for (const auto& p : points)
  {
    pts.emplace_back(p.x(), p.y());
  }
  Shape shape(pts.begin(), pts.end(), K::FT(alpha_m * alpha_m), Shape::GENERAL);
  std::set<Edge2> regular, singular;
  for (auto it = shape.alpha_shape_edges_begin(); it != shape.alpha_shape_edges_end(); ++it)
  {
    Shape::Face_handle f = it->first;
    int i = it->second;
    if (shape.classify(*it) == Shape::SINGULAR)
    {
      auto a = f->vertex(Shape::ccw(i))->point(), b = f->vertex(Shape::cw(i))->point();
      if (b < a)
      {
        std::swap(a, b);
      }
      singular.emplace(a.x(), a.y(), b.x(), b.y());
      continue;
    }
    if (shape.classify(f) != Shape::INTERIOR)
    {
      const Shape::Face_handle g = f->neighbor(i);
      i = g->index(f);
      f = g;
    }
    const auto a = f->vertex(Shape::ccw(i))->point(), b = f->vertex(Shape::cw(i))->point();
    regular.emplace(a.x(), a.y(), b.x(), b.y());
  }
  return { regular, singular };
}
}  // namespace

TEST(AlphaShape, SameEdgesAsCgalAlphaShape2)
{
  // Points on a cell grid, as GridBuilder passes them: full of cocircular and equidistant points,
  // so every tie of a face radius or half edge length with alpha is exercised.
  std::mt19937 rng(7);
  for (int trial = 0; trial < 40; ++trial)
  {
    const int side = 8 + trial;
    std::uniform_int_distribution<int> coord(0, side);
    PointList2D points;
    std::set<std::pair<int, int>> used;
    const int n = 10 + 6 * trial;
    while (static_cast<int>(points.size()) < n)
    {
      const int x = coord(rng), y = coord(rng);
      if (used.emplace(x, y).second)
      {
        points.emplace_back(x, y);
      }
    }
    for (const double alpha : { 1.0, 1.5, std::sqrt(2.0), 2.0, 2.5, 4.0 })
    {
      const auto reference = cgalAlphaShape(points, alpha);
      const auto ours = sparse_nav::computeAlphaShape(points, alpha);
      std::set<Edge2> regular, singular;
      for (const auto& ring : ours.rings)
      {
        for (std::size_t k = 0; k < ring.size(); ++k)
        {
          const auto& a = ring[k];
          const auto& b = ring[(k + 1) % ring.size()];
          regular.emplace(a.x(), a.y(), b.x(), b.y());
        }
      }
      for (const auto& seg : ours.segments)
      {
        auto a = seg.first, b = seg.second;
        if (b.x() < a.x() || (b.x() == a.x() && b.y() < a.y()))
        {
          std::swap(a, b);
        }
        singular.emplace(a.x(), a.y(), b.x(), b.y());
      }
      EXPECT_EQ(regular, reference.first) << "trial " << trial << ", alpha " << alpha;
      EXPECT_EQ(singular, reference.second) << "trial " << trial << ", alpha " << alpha;
    }
  }
}

TEST(AlphaShape, RingsDoNotDependOnTheOrderOfThePoints)
{
  // Grid points are full of cocircular quadruples, whose triangulation, and the order in which it
  // lists its edges, change with the order of insertion (and with the heap): the rings must not.
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> coord(0, 60);
  std::set<std::pair<int, int>> cells;
  while (cells.size() < 900)
  {
    const int x = coord(rng), y = coord(rng);
    cells.emplace(x, y % 12 == 0 ? y : (x % 10 == 0 ? y : y / 3 * 3));
  }
  PointList2D points;
  for (const auto& c : cells)
  {
    points.emplace_back(c.first, c.second);
  }
  const auto first = sparse_nav::computeAlphaShape(points, 1.5);
  ASSERT_GT(first.rings.size(), 1u);
  for (int trial = 0; trial < 5; ++trial)
  {
    std::shuffle(points.begin(), points.end(), rng);
    EXPECT_TRUE(sparse_nav::computeAlphaShape(points, 1.5).rings == first.rings) << "shuffle " << trial;
  }
}

TEST(Rasterisation, KnownSquareCells)
{
  // Outline of a 21 x 21-cell square every 2 cells.
  PointList2D pts;
  for (int k = 0; k <= 20; k += 2)
  {
    pts.push_back(cell(k, 0));
    pts.push_back(cell(k, 20));
    pts.push_back(cell(0, k));
    pts.push_back(cell(20, k));
  }
  GridBuilderConfig cfg;
  cfg.padding_m = 0.0;
  cfg.alpha.alpha_m = 1.0;  // larger than the square's circumradius (0.71 m): filled
  GridBuilder filled(cfg);
  ASSERT_TRUE(filled.update(pts, {}).ok);
  EXPECT_EQ(filled.grid().count(OccupancyGrid::kOccupied), 21u * 21u);
  EXPECT_EQ(filled.grid().count(OccupancyGrid::kFree), 0u);
  EXPECT_EQ(filled.grid().width % cfg.tile_size_cells, 0);
  EXPECT_DOUBLE_EQ(filled.grid().origin_x_m, 0.0);

  cfg.alpha.alpha_m = 0.06;  // gaps of 0.1 m close, the inside stays empty: the outline only
  GridBuilder outline(cfg);
  ASSERT_TRUE(outline.update(pts, {}).ok);
  EXPECT_EQ(outline.grid().count(OccupancyGrid::kOccupied), 80u);
  EXPECT_EQ(valueAt(outline.grid(), cell(10, 10).x(), cell(10, 10).y()), OccupancyGrid::kUnknown);
}

TEST(DirtyTiles, ChangingOneCornerRecomputesOnlyNearbyTilesAndMatchesAFullRebuild)
{
  PointList2D pts;
  std::vector<FreeRay> rays;
  sparseRoom(pts, rays);
  // A bigger area so that the corner is far from most tiles: add a far wall segment.
  for (int i = 300; i <= 400; i += 4)
  {
    pts.push_back(cell(i, 300));
  }
  GridBuilder incremental;
  const GridUpdate first = incremental.update(pts, rays);
  ASSERT_TRUE(first.full_rebuild);
  const int n_tiles = (incremental.grid().width / 32) * (incremental.grid().height / 32);
  EXPECT_EQ(static_cast<int>(first.recomputed_tiles.size()), n_tiles);

  // Same input again: nothing to do.
  const GridUpdate same = incremental.update(pts, rays);
  EXPECT_FALSE(same.full_rebuild);
  EXPECT_TRUE(same.recomputed_tiles.empty());
  EXPECT_TRUE(same.changed_tiles.empty());

  // Change the far corner: a few points added near (19.5, 15.5) m, one removed.
  PointList2D changed = pts;
  changed.pop_back();
  for (int k = 0; k < 5; ++k)
  {
    changed.push_back(cell(385 + k, 305));
  }
  const GridUpdate u = incremental.update(changed, rays);
  ASSERT_TRUE(u.ok);
  EXPECT_FALSE(u.full_rebuild);
  ASSERT_FALSE(u.recomputed_tiles.empty());
  EXPECT_LT(static_cast<int>(u.recomputed_tiles.size()), n_tiles / 4);
  const int col0 = incremental.grid().colOf(cell(385, 305).x()) / 32;
  const int row0 = incremental.grid().rowOf(cell(385, 305).y()) / 32;
  for (const auto& t : u.recomputed_tiles)
  {
    EXPECT_LE(std::abs(t.tx - col0), 3) << t.tx << "," << t.ty;
    EXPECT_LE(std::abs(t.ty - row0), 3) << t.tx << "," << t.ty;
  }
  EXPECT_FALSE(u.changed_tiles.empty());
  EXPECT_LT(u.min_col, u.max_col);
  EXPECT_LT(u.min_row, u.max_row);

  GridBuilder fresh;
  ASSERT_TRUE(fresh.update(changed, rays).ok);
  ASSERT_EQ(fresh.grid().width, incremental.grid().width);
  ASSERT_EQ(fresh.grid().height, incremental.grid().height);
  EXPECT_DOUBLE_EQ(fresh.grid().origin_x_m, incremental.grid().origin_x_m);
  EXPECT_EQ(fresh.grid().data, incremental.grid().data);

  // Changing a ray also recomputes the tiles it crosses, and still matches a full rebuild.
  std::vector<FreeRay> rays2 = rays;
  rays2.push_back(FreeRay{ Eigen::Vector2d(2.5, 2.0), Eigen::Vector2d(4.0, 3.0) });
  rays2.erase(rays2.begin());
  incremental.update(changed, rays2);
  GridBuilder fresh2;
  fresh2.update(changed, rays2);
  EXPECT_EQ(fresh2.grid().data, incremental.grid().data);
}

TEST(DirtyTiles, RemovingARayForgetsOnlyTheCellsNoOtherRaySaw)
{
  const PointList2D pts{ { 3.2, 0.5 }, { 0.5, 3.2 } };
  const FreeRay long_ray{ Eigen::Vector2d(0.52, 0.52), Eigen::Vector2d(3.02, 0.52) };
  const FreeRay short_ray{ Eigen::Vector2d(0.52, 0.52), Eigen::Vector2d(1.52, 0.52) };
  const FreeRay side_ray{ Eigen::Vector2d(0.52, 0.52), Eigen::Vector2d(0.52, 3.02) };
  GridBuilder builder;
  ASSERT_TRUE(builder.update(pts, { long_ray, short_ray, side_ray }).full_rebuild);
  EXPECT_EQ(valueAt(builder.grid(), 2.52, 0.52), OccupancyGrid::kFree);
  EXPECT_EQ(valueAt(builder.grid(), 1.02, 0.52), OccupancyGrid::kFree);

  const GridUpdate without = builder.update(pts, { short_ray, side_ray });
  ASSERT_FALSE(without.full_rebuild);
  EXPECT_EQ(valueAt(builder.grid(), 2.52, 0.52), OccupancyGrid::kUnknown);
  EXPECT_EQ(valueAt(builder.grid(), 1.02, 0.52), OccupancyGrid::kFree);  // the short ray still sees it
  GridBuilder fresh;
  fresh.update(pts, { short_ray, side_ray });
  EXPECT_EQ(fresh.grid().data, builder.grid().data);

  ASSERT_FALSE(builder.update(pts, { long_ray, short_ray, side_ray }).full_rebuild);
  EXPECT_EQ(valueAt(builder.grid(), 2.52, 0.52), OccupancyGrid::kFree);
}

TEST(DirtyTiles, GrowthForcesAFullRebuild)
{
  GridBuilder builder;
  builder.update(PointList2D{ cell(0, 0), cell(10, 0) }, {});
  const int w = builder.grid().width;
  const GridUpdate u = builder.update(PointList2D{ cell(0, 0), cell(10, 0), cell(200, 0) }, {});
  EXPECT_TRUE(u.full_rebuild);
  EXPECT_GT(builder.grid().width, w);
}

TEST(GridBuilder, RepeatedRaysCountOnceNearByOrKilometresApart)
{
  const FreeRay near_a{ Eigen::Vector2d(0.02, 0.02), Eigen::Vector2d(1.02, 0.02) };
  const FreeRay near_b{ Eigen::Vector2d(0.02, 0.02), Eigen::Vector2d(0.02, 1.02) };
  GridBuilder nearby;
  const GridUpdate u = nearby.update({}, { near_a, near_b, near_a, near_b, near_a });
  ASSERT_TRUE(u.ok) << u.status;
  EXPECT_EQ(u.n_rays, 2u);
  EXPECT_EQ(valueAt(nearby.grid(), 0.52, 0.02), OccupancyGrid::kFree);
  EXPECT_EQ(valueAt(nearby.grid(), 0.02, 0.52), OccupancyGrid::kFree);

  // 4 km apart: more than 65536 cells, the rays cannot share one packed sort key.
  const FreeRay far{ Eigen::Vector2d(4000.02, 0.02), Eigen::Vector2d(4001.02, 0.02) };
  GridBuilder spread;
  const GridUpdate v = spread.update({}, { far, near_a, far, near_a });
  ASSERT_TRUE(v.ok) << v.status;
  EXPECT_EQ(v.n_rays, 2u);
  EXPECT_EQ(valueAt(spread.grid(), 0.52, 0.02), OccupancyGrid::kFree);
  EXPECT_EQ(valueAt(spread.grid(), 4000.52, 0.02), OccupancyGrid::kFree);
  EXPECT_EQ(valueAt(spread.grid(), 2000.0, 0.02), OccupancyGrid::kUnknown);
}

TEST(GridBuilder, RepeatedObstacleCellsCountOnceOverTheWholeAcceptedRange)
{
  // Cells from -1e9 to 1e9 along both axes (update() drops points beyond 1e9 cells), each point
  // given twice and once more elsewhere in its cell: only distinct cells count. So wide a cloud is
  // refused as a grid, but the cells are counted and the extent reported first.
  const double res = GridBuilderConfig().resolution_m;
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> coordinate(-1e9 * res, 1e9 * res);
  std::uniform_real_distribution<double> within(0.001, 0.999);
  PointList2D obstacles = { { -1e9 * res, -1e9 * res }, { 1e9 * res - 0.5 * res, 1e9 * res - 0.5 * res } };
  std::set<std::pair<std::int64_t, std::int64_t>> distinct;
  for (int i = 0; i < 5000; ++i)
  {
    const Eigen::Vector2d p(coordinate(rng), i % 2 ? coordinate(rng) : std::round(coordinate(rng) / 1e7));
    obstacles.push_back(p);
    obstacles.push_back(p);
    const Eigen::Vector2d corner(std::floor(p.x() / res) * res, std::floor(p.y() / res) * res);
    obstacles.push_back(corner + res * Eigen::Vector2d(within(rng), within(rng)));
  }
  for (const auto& p : obstacles)
  {
    distinct.emplace(static_cast<std::int64_t>(std::floor(p.y() / res)), static_cast<std::int64_t>(std::floor(p.x() / res)));
  }
  std::int64_t min_x = distinct.begin()->second, max_x = min_x;
  for (const auto& c : distinct)
  {
    min_x = std::min(min_x, c.second);
    max_x = std::max(max_x, c.second);
  }
  const double span_y = static_cast<double>(distinct.rbegin()->first - distinct.begin()->first + 1) * res;
  char span[100];
  std::snprintf(span, sizeof(span), "spans %.0f x %.0f m", static_cast<double>(max_x - min_x + 1) * res, span_y);
  GridBuilder builder;
  const GridUpdate u = builder.update(obstacles, {});
  EXPECT_FALSE(u.ok);
  EXPECT_NE(u.status.find("max_cells"), std::string::npos);
  EXPECT_EQ(u.n_obstacle_cells, distinct.size());
  EXPECT_NE(u.status.find(span), std::string::npos) << u.status << " lacks " << span;
}

TEST(GridBuilder, RaysCrossingALineBetweenTwoPointsKeepItOpenButNotAnArea)
{
  // Two walls two cells thick, their ends 0.35 m apart: alpha 0.2 m joins the ends by singular
  // edges (the triangles across the gap are too large). Rays pass through the gap.
  PointList2D pts;
  for (int i = 0; i <= 10; ++i)
  {
    const double y = i % 2 ? 0.075 : 0.025;
    pts.emplace_back(0.025 + 0.1 * i, y);
    pts.emplace_back(1.375 + 0.1 * i, y);
  }
  std::vector<FreeRay> rays;
  for (int k = 0; k < 5; ++k)
  {
    const double x = 1.075 + 0.05 * k;  // cell centres: two rays through each gap cell
    rays.push_back(FreeRay{ Eigen::Vector2d(x, 1.0), Eigen::Vector2d(x, -1.0) });
    rays.push_back(FreeRay{ Eigen::Vector2d(x + 0.01, 1.5), Eigen::Vector2d(x - 0.01, -1.5) });
  }
  GridBuilderConfig cfg;  // clear_segment_min_rays 2
  cfg.alpha.alpha_m = 0.2;
  GridBuilder builder(cfg);
  ASSERT_TRUE(builder.update(pts, rays).ok);
  EXPECT_EQ(valueAt(builder.grid(), 1.225, 0.025), OccupancyGrid::kFree);
  EXPECT_EQ(valueAt(builder.grid(), 0.525, 0.025), OccupancyGrid::kOccupied) << "the wall stays";
  GridBuilderConfig off = cfg;
  off.clear_segment_min_rays = 0;
  GridBuilder closed(off);
  ASSERT_TRUE(closed.update(pts, rays).ok);
  EXPECT_EQ(valueAt(closed.grid(), 1.225, 0.025), OccupancyGrid::kOccupied);

  // The outline of a 0.6 m square (alpha 0.4 m fills it): rays across its inside leave it
  // occupied, as they do inside a noisy wall band, where rays reach the band's far points.
  PointList2D square;
  for (int i = 0; i < 6; ++i)
  {
    const double t = 0.025 + 0.1 * i;
    square.emplace_back(t, 0.025);
    square.emplace_back(t, 0.525);
    square.emplace_back(0.025, t);
    square.emplace_back(0.525, t);
  }
  std::vector<FreeRay> across;
  for (int k = 0; k < 5; ++k)
  {
    across.push_back(FreeRay{ Eigen::Vector2d(0.075 + 0.1 * k, 1.5), Eigen::Vector2d(0.275, 0.275) });
  }
  GridBuilderConfig wide;
  wide.alpha.alpha_m = 0.4;
  GridBuilder area(wide);
  ASSERT_TRUE(area.update(square, across).ok);
  EXPECT_EQ(valueAt(area.grid(), 0.3, 0.3), OccupancyGrid::kOccupied);
  EXPECT_EQ(valueAt(area.grid(), 0.275, 0.4), OccupancyGrid::kOccupied);
}

TEST(GridBuilder, EmptyInputGivesAnEmptyGridWithAStatus)
{
  GridBuilder builder;
  const GridUpdate u = builder.update({}, {});
  EXPECT_TRUE(u.ok);
  EXPECT_TRUE(builder.grid().empty());
  EXPECT_NE(u.status.find("empty grid"), std::string::npos);
}

TEST(GridBuilder, HugeExtentIsRefusedAndTheGridKept)
{
  GridBuilder builder;
  builder.update(PointList2D{ cell(0, 0), cell(10, 0) }, {});
  const auto before = builder.grid().data;
  const GridUpdate u = builder.update(PointList2D{ cell(0, 0), { 1e6, 1e6 } }, {});
  EXPECT_FALSE(u.ok);
  EXPECT_NE(u.status.find("max_cells"), std::string::npos);
  EXPECT_EQ(builder.grid().data, before);
}

TEST(GridBuilder, ConfigValidation)
{
  GridBuilderConfig cfg;
  cfg.alpha.alpha_m = 0;
  EXPECT_THROW(GridBuilder{ cfg }, std::invalid_argument);
  cfg = GridBuilderConfig();
  cfg.tile_size_cells = 1;
  EXPECT_THROW(cfg.validate(), std::invalid_argument);
  cfg = GridBuilderConfig();
  cfg.clear_segment_min_rays = -1;
  EXPECT_THROW(cfg.validate(), std::invalid_argument);
}

TEST(RadixSort, AgreesWithStdSort)
{
  std::mt19937_64 rng(4);
  // Keys that differ in every bit, keys with equal high bits (packed cells), repeats, and the
  // trivial cases.
  std::vector<std::vector<std::uint64_t>> cases{ {}, { 7 }, { 5, 5, 5 } };
  std::vector<std::uint64_t> wide, packed, repeats;
  for (int i = 0; i < 30000; ++i)
  {
    wide.push_back(rng());
    packed.push_back(0x8000400020000000ULL + (rng() % 600) * 0x100000000ULL + rng() % 5000);
    repeats.push_back(rng() % 97 << 40);
  }
  wide.push_back(~std::uint64_t{ 0 });
  wide.push_back(0);
  cases.push_back(wide);
  cases.push_back(packed);
  cases.push_back(repeats);
  for (auto keys : cases)
  {
    std::vector<std::uint64_t> expected = keys;
    std::sort(expected.begin(), expected.end());
    sparse_nav::radixSort(keys);
    EXPECT_EQ(keys, expected);
  }
}

TEST(GridBuilder, AFullBuildCoversTheCellsOfEachRayAsAWalkOfItAloneDoes)
{
  // A full build walks its rays four at a time; an update walks the rays it is given one by one.
  // Built from all the rays at once, or from three and then the rest as a change, the grid is the
  // same: rays of every length and direction, from one camera and from others, repeated, and ones
  // that end in their start cell.
  std::mt19937 rng(41);
  std::uniform_real_distribution<double> u(0.0, 6.0);
  PointList2D obstacles;
  std::vector<FreeRay> rays;
  const std::vector<Eigen::Vector2d> cameras{ { 3.0, 3.0 }, { 0.7, 5.1 }, { 5.3, 0.4 } };
  for (int i = 0; i < 997; ++i)
  {
    const Eigen::Vector2d end(u(rng), u(rng));
    const Eigen::Vector2d& from = cameras[static_cast<std::size_t>(i) % cameras.size()];
    obstacles.push_back(end);
    rays.push_back(FreeRay{ from, i % 50 == 0 ? from + Eigen::Vector2d(0.01, 0.01) : end });
  }
  obstacles.insert(obstacles.end(), cameras.begin(), cameras.end());
  GridBuilder all_at_once, three_then_rest;
  all_at_once.update(obstacles, rays);
  sparse_nav::GridChange rest;
  rest.rays_added.assign(rays.begin() + 3, rays.end());
  three_then_rest.update(obstacles, std::vector<FreeRay>(rays.begin(), rays.begin() + 3));
  const GridUpdate updated = three_then_rest.update(obstacles, [&] { return rays; }, rest);
  ASSERT_TRUE(updated.ok);
  EXPECT_FALSE(updated.full_rebuild);
  ASSERT_EQ(three_then_rest.grid().data.size(), all_at_once.grid().data.size());
  EXPECT_TRUE(three_then_rest.grid().data == all_at_once.grid().data);
  EXPECT_GT(all_at_once.grid().count(OccupancyGrid::kFree), 1000u);
}

TEST(GridBuilder, AnUpdateByTheChangeGivesTheGridOfTheWholeLists)
{
  // A room's walls and rays to them from a camera, with repeated points and rays; each round some
  // wall points move, some go, new ones come, and rays follow them. The builder updated by the
  // change alone must match one given the whole lists every round, cell for cell.
  std::mt19937 rng(29);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const Eigen::Vector2d camera(2.5, 2.0);
  auto wallPoint = [&]() {
    const double s = u(rng);
    switch (static_cast<int>(u(rng) * 4))
    {
      case 0:
        return Eigen::Vector2d(5.0 * s, 0.0 + 0.02 * u(rng));
      case 1:
        return Eigen::Vector2d(5.0 - 0.02 * u(rng), 4.0 * s);
      case 2:
        return Eigen::Vector2d(5.0 * s, 4.0 - 0.02 * u(rng));
      default:
        return Eigen::Vector2d(0.02 * u(rng), 4.0 * s);
    }
  };
  PointList2D obstacles;
  std::vector<FreeRay> rays;
  for (int i = 0; i < 3000; ++i)
  {
    obstacles.push_back(wallPoint());
    rays.push_back(FreeRay{ camera, obstacles.back() });
    if (i % 10 == 0)
    {
      obstacles.push_back(obstacles.back());  // the same point twice
      rays.push_back(rays.back());
    }
  }
  GridBuilder incremental, whole;
  incremental.update(obstacles, rays);
  whole.update(obstacles, rays);
  for (int round = 0; round < 6; ++round)
  {
    sparse_nav::GridChange change;
    for (std::size_t i = 0; i < obstacles.size(); ++i)
    {
      const double t = u(rng);
      if (t < 0.03)
      {
        change.obstacles_removed.push_back(obstacles[i]);
        change.rays_removed.push_back(rays[i]);
        obstacles[i] = t < 0.015 ? wallPoint() : Eigen::Vector2d(0.5 + 4.0 * u(rng), 0.5 + 3.0 * u(rng));
        rays[i] = FreeRay{ camera, obstacles[i] };
        change.obstacles_added.push_back(obstacles[i]);
        change.rays_added.push_back(rays[i]);
      }
    }
    const GridUpdate a = incremental.update(obstacles, [&] { return rays; }, change);
    const GridUpdate b = whole.update(obstacles, rays);
    ASSERT_TRUE(a.ok) << a.status;
    EXPECT_FALSE(a.full_rebuild);
    EXPECT_EQ(a.n_rays, b.n_rays) << "round " << round;
    EXPECT_EQ(a.n_obstacle_cells, b.n_obstacle_cells) << "round " << round;
    EXPECT_LT(a.recomputed_tiles.size(), 2 * b.recomputed_tiles.size() + 1);
    ASSERT_EQ(incremental.grid().data.size(), whole.grid().data.size());
    EXPECT_TRUE(incremental.grid().data == whole.grid().data) << "round " << round;
  }
  // A change reaching beyond the grid grows it, as the whole lists do.
  sparse_nav::GridChange far;
  far.obstacles_added.push_back(Eigen::Vector2d(12.0, 2.0));
  far.rays_added.push_back(FreeRay{ camera, Eigen::Vector2d(12.0, 2.0) });
  obstacles.push_back(far.obstacles_added.back());
  rays.push_back(far.rays_added.back());
  const GridUpdate grown = incremental.update(obstacles, [&] { return rays; }, far);
  EXPECT_TRUE(grown.full_rebuild);
  whole.update(obstacles, rays);
  EXPECT_TRUE(incremental.grid().data == whole.grid().data);
  // A change that removes what the builder never held starts again from the lists.
  sparse_nav::GridChange wrong;
  wrong.rays_removed.push_back(FreeRay{ Eigen::Vector2d(1.0, 1.0), Eigen::Vector2d(1.3, 1.1) });
  const GridUpdate restarted = incremental.update(obstacles, [&] { return rays; }, wrong);
  EXPECT_TRUE(restarted.full_rebuild);
  EXPECT_TRUE(incremental.grid().data == whole.grid().data);
}
