#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include <CGAL/Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include "sparse_nav/core/grid_builder.h"

namespace sparse_nav
{
namespace
{
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point2 = Kernel::Point_2;
using Delaunay = CGAL::Delaunay_triangulation_2<Kernel>;
using Face = Delaunay::Face_handle;

Delaunay triangulate(const PointList2D& points)
{
  std::vector<Point2> cgal_points;
  cgal_points.reserve(points.size());
  for (const auto& p : points)
  {
    cgal_points.emplace_back(p.x(), p.y());
  }
  return Delaunay(cgal_points.begin(), cgal_points.end());
}

Eigen::Vector2d toEigen(const Point2& p)
{
  return Eigen::Vector2d(p.x(), p.y());
}

/// Edges of a degenerate (collinear) set: consecutive points not further apart than 2 * alpha.
void collinearSegments(const PointList2D& points, double alpha_m, AlphaShapeResult& out)
{
  if (points.size() < 2)
  {
    return;
  }
  PointList2D sorted = points;
  std::sort(sorted.begin(), sorted.end(), [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  for (std::size_t i = 1; i < sorted.size(); ++i)
  {
    if ((sorted[i] - sorted[i - 1]).norm() <= 2.0 * alpha_m)
    {
      out.segments.emplace_back(sorted[i - 1], sorted[i]);
    }
  }
}
}  // namespace

void AlphaShapeConfig::validate() const
{
  if (!(alpha_m > 0.0) || !std::isfinite(alpha_m))
  {
    throw std::invalid_argument("AlphaShapeConfig: alpha_m must be finite and > 0");
  }
  if (!(auto_alpha_percentile >= 0.0 && auto_alpha_percentile <= 100.0))
  {
    throw std::invalid_argument("AlphaShapeConfig: auto_alpha_percentile must be in [0, 100]");
  }
  if (!(auto_alpha_factor > 0.0) || !std::isfinite(auto_alpha_factor))
  {
    throw std::invalid_argument("AlphaShapeConfig: auto_alpha_factor must be finite and > 0");
  }
  if (!(max_auto_alpha_m > 0.0) || !std::isfinite(max_auto_alpha_m))
  {
    throw std::invalid_argument("AlphaShapeConfig: max_auto_alpha_m must be finite and > 0");
  }
}

AlphaShapeResult computeAlphaShape(const PointList2D& points, double alpha_m)
{
  AlphaShapeResult out;
  out.alpha_m = alpha_m;
  if (points.size() < 2)
  {
    return out;
  }
  const Delaunay dt = triangulate(points);
  if (dt.dimension() < 2)
  {
    collinearSegments(points, alpha_m, out);
    return out;
  }
  // CGAL's Alpha_shape_2 classification (GENERAL mode) for one alpha, read straight off the
  // triangulation: Alpha_shape_2 would first build and sort the alpha intervals of every face,
  // edge and vertex (the whole spectrum), most of the cost when only one alpha is ever asked for.
  // A face is interior when its squared circumradius is <= alpha^2; an edge with one interior
  // face is regular; an edge with none is singular when alpha reaches its half length and no
  // incident triangle's third vertex lies strictly inside its diametral circle.
  const double alpha2 = alpha_m * alpha_m;
  const auto squared_radius = Kernel().compute_squared_radius_2_object();
  const auto side_of_bounded_circle = Kernel().side_of_bounded_circle_2_object();
  auto faceAlpha2 = [&](const Face& f) {
    return dt.is_infinite(f) ? std::numeric_limits<double>::infinity()
                             : squared_radius(f->vertex(0)->point(), f->vertex(1)->point(), f->vertex(2)->point());
  };
  auto attached = [&](const Face& f, int i) {
    return !dt.is_infinite(f) && side_of_bounded_circle(f->vertex(Delaunay::cw(i))->point(),
                                                        f->vertex(Delaunay::ccw(i))->point(),
                                                        f->vertex(i)->point()) == CGAL::ON_BOUNDED_SIDE;
  };
  // Regular edges oriented with the interior on their left.
  std::vector<std::pair<Point2, Point2>> regular;
  for (auto it = dt.finite_edges_begin(); it != dt.finite_edges_end(); ++it)
  {
    Face f = it->first;
    int i = it->second;
    const Face g = f->neighbor(i);
    const int j = g->index(f);
    const double alpha_f = faceAlpha2(f), alpha_g = faceAlpha2(g);
    if (alpha2 < std::min(alpha_f, alpha_g))
    {
      const Point2& a = f->vertex(Delaunay::ccw(i))->point();
      const Point2& b = f->vertex(Delaunay::cw(i))->point();
      if (!attached(f, i) && !attached(g, j) && alpha2 >= squared_radius(a, b))
      {
        out.segments.emplace_back(toEigen(a), toEigen(b));
      }
      continue;
    }
    if (alpha2 >= std::max(alpha_f, alpha_g))
    {
      continue;  // interior
    }
    if (alpha_f > alpha2)
    {
      f = g;
      i = j;
    }
    const Point2& a = f->vertex(Delaunay::ccw(i))->point();
    const Point2& b = f->vertex(Delaunay::cw(i))->point();
    regular.emplace_back(a, b);
  }
  // Chain into closed rings: every vertex has as many regular edges in as out, so a walk from an
  // edge comes back to its start. At a vertex where rings touch any continuation is valid (the
  // even-odd fill of the rings depends only on the set of edges); the first unused edge in
  // (start, end) order is taken. The triangulation's own order of its edges is not fixed: on grid
  // points, full of cocircular quadruples, it changed with the state of the heap, and rings
  // chained in it with it (their count, not their fill).
  auto lexLess = [](const Point2& p, const Point2& q) { return p.x() < q.x() || (p.x() == q.x() && p.y() < q.y()); };
  std::sort(regular.begin(), regular.end(), [&](const std::pair<Point2, Point2>& e, const std::pair<Point2, Point2>& f) {
    return lexLess(e.first, f.first) || (e.first == f.first && lexLess(e.second, f.second));
  });
  std::vector<char> used(regular.size(), 0);
  auto unusedFrom = [&](const Point2& p) {
    auto it = std::lower_bound(regular.begin(), regular.end(), p,
                               [&](const std::pair<Point2, Point2>& e, const Point2& q) { return lexLess(e.first, q); });
    for (; it != regular.end() && it->first == p; ++it)
    {
      if (!used[static_cast<std::size_t>(it - regular.begin())])
      {
        return static_cast<std::size_t>(it - regular.begin());
      }
    }
    return regular.size();
  };
  for (std::size_t first = 0; first < regular.size(); ++first)
  {
    if (used[first])
    {
      continue;
    }
    used[first] = 1;
    const Point2 start = regular[first].first;
    Point2 current = regular[first].second;
    std::vector<Eigen::Vector2d> ring{ toEigen(start) };
    while (!(current == start))
    {
      ring.push_back(toEigen(current));
      const std::size_t next = unusedFrom(current);
      if (next == regular.size())
      {
        break;
      }
      used[next] = 1;
      current = regular[next].second;
    }
    if (ring.size() >= 3)
    {
      out.rings.push_back(std::move(ring));
    }
  }
  return out;
}

double automaticAlpha(const PointList2D& points, const AlphaShapeConfig& config, double resolution_m)
{
  const double upper = std::max(config.max_auto_alpha_m, resolution_m);
  if (points.size() < 2)
  {
    return std::min(config.alpha_m, upper);
  }
  const Delaunay dt = triangulate(points);
  // The nearest neighbour of a point is always one of its Delaunay neighbours.
  std::vector<double> spacing;
  spacing.reserve(dt.number_of_vertices());
  for (auto v = dt.finite_vertices_begin(); v != dt.finite_vertices_end(); ++v)
  {
    double best = std::numeric_limits<double>::infinity();
    auto c = dt.incident_vertices(v), done = c;
    if (c != nullptr)
    {
      do
      {
        if (!dt.is_infinite(c))
        {
          best = std::min(best, std::sqrt(CGAL::to_double(CGAL::squared_distance(v->point(), c->point()))));
        }
      } while (++c != done);
    }
    if (std::isfinite(best))
    {
      spacing.push_back(best);
    }
  }
  if (spacing.empty())
  {
    return std::min(config.alpha_m, upper);
  }
  const std::size_t k = static_cast<std::size_t>(
      std::lround(config.auto_alpha_percentile / 100.0 * static_cast<double>(spacing.size() - 1)));
  std::nth_element(spacing.begin(), spacing.begin() + static_cast<std::ptrdiff_t>(k), spacing.end());
  const double alpha = config.auto_alpha_factor * spacing[k];
  return std::max(resolution_m, std::min(upper, alpha));
}

}  // namespace sparse_nav
