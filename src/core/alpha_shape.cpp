#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
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
  // Regular edges oriented with the interior on their left, keyed by their start vertex.
  std::multimap<std::pair<double, double>, std::pair<Point2, Point2>> outgoing;
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
    outgoing.emplace(std::make_pair(a.x(), a.y()), std::make_pair(a, b));
  }
  // Chain into closed rings. At a vertex where rings touch any continuation is valid: the even-odd
  // fill of the rings depends only on the set of edges.
  while (!outgoing.empty())
  {
    auto first = outgoing.begin();
    const Point2 start = first->second.first;
    Point2 current = first->second.second;
    std::vector<Eigen::Vector2d> ring{ toEigen(start) };
    outgoing.erase(first);
    while (!(current == start))
    {
      ring.push_back(toEigen(current));
      auto next = outgoing.find(std::make_pair(current.x(), current.y()));
      if (next == outgoing.end())
      {
        break;
      }
      current = next->second.second;
      outgoing.erase(next);
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
