#ifndef SPARSE_NAV_TEST_CORE_SYNTHETIC_H
#define SPARSE_NAV_TEST_CORE_SYNTHETIC_H

// Deterministic synthetic clouds for the core tests: rooms with walls, a door gap, a floor.

#include <cmath>
#include <random>

#include <Eigen/Geometry>

#include "sparse_nav/core/types.h"

namespace sparse_nav
{
namespace test
{
/// Points on a wall segment from (x0, y0) to (x1, y1), heights z in [z0, z1], spacing `step`,
/// skipping the gap [gap_from, gap_to] (distance along the wall, metres).
inline void addWall(PointList& out, double x0, double y0, double x1, double y1, double z0, double z1, double step,
                    double gap_from = -1.0, double gap_to = -1.0)
{
  const double len = std::hypot(x1 - x0, y1 - y0);
  for (double s = 0.0; s <= len + 1e-9; s += step)
  {
    if (s >= gap_from && s <= gap_to)
    {
      continue;
    }
    const double t = s / len;
    for (double z = z0; z <= z1 + 1e-9; z += step)
    {
      out.emplace_back(static_cast<float>(x0 + t * (x1 - x0)), static_cast<float>(y0 + t * (y1 - y0)),
                       static_cast<float>(z));
    }
  }
}

/// Floor points on z = 0 over [x0, x1] x [y0, y1].
inline void addFloor(PointList& out, double x0, double y0, double x1, double y1, double step)
{
  for (double x = x0; x <= x1 + 1e-9; x += step)
  {
    for (double y = y0; y <= y1 + 1e-9; y += step)
    {
      out.emplace_back(static_cast<float>(x), static_cast<float>(y), 0.0f);
    }
  }
}

/// A w x d room in a z-up frame: four walls (height 2 m), a door gap of `door` metres in the
/// wall y = 0 starting 1 m from x = 0, a floor, Gaussian noise sigma `noise` with a fixed seed.
inline PointList makeRoom(double w = 5.0, double d = 4.0, double door = 0.9, double step = 0.1, double noise = 0.005,
                          unsigned seed = 7)
{
  PointList pts;
  addWall(pts, 0, 0, w, 0, 0.3, 2.0, step, 1.0, 1.0 + door);
  addWall(pts, w, 0, w, d, 0.3, 2.0, step);
  addWall(pts, w, d, 0, d, 0.3, 2.0, step);
  addWall(pts, 0, d, 0, 0, 0.3, 2.0, step);
  addFloor(pts, 0.2, 0.2, w - 0.2, d - 0.2, step);
  std::mt19937 rng(seed);
  std::normal_distribution<float> n(0.0f, static_cast<float>(noise));
  for (auto& p : pts)
  {
    p += Eigen::Vector3f(n(rng), n(rng), n(rng));
  }
  return pts;
}

/// Rotation taking z-up points into a raw ORB-SLAM-like frame (y down): inverse of the "-y up" map.
inline Eigen::Isometry3d zUpToYDown()
{
  Eigen::Matrix3d r;
  // map (x, y, z) -> slam (x, -z, y): slam y is down, slam z is forward.
  r << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = r;
  return t;
}

}  // namespace test
}  // namespace sparse_nav

#endif  // SPARSE_NAV_TEST_CORE_SYNTHETIC_H
