#ifndef SPARSE_NAV_CORE_BRESENHAM_H
#define SPARSE_NAV_CORE_BRESENHAM_H

// Private helper of sparse_nav_core (not installed): the grid's line walk.

#include <algorithm>
#include <cstdlib>

namespace sparse_nav
{
/// Integer Bresenham over every cell from (x0, y0) to (x1, y1), both included: max(|dx|, |dy|) + 1
/// cells, visited in order. The steps are chosen without branches (a branch on them mispredicts
/// along most lines).
template <typename Visit>
void bresenham(int x0, int y0, int x1, int y1, Visit visit)
{
  const int dx = std::abs(x1 - x0);
  const int dy = -std::abs(y1 - y0);
  const int sx = x0 < x1 ? 1 : -1;
  const int sy = y0 < y1 ? 1 : -1;
  int err = dx + dy;
  for (int n = std::max(dx, -dy); n >= 0; --n)
  {
    visit(x0, y0);
    const int e2 = 2 * err;
    const bool step_x = e2 >= dy;
    const bool step_y = e2 <= dx;
    err += (step_x ? dy : 0) + (step_y ? dx : 0);
    x0 += step_x ? sx : 0;
    y0 += step_y ? sy : 0;
  }
}
}  // namespace sparse_nav

#endif  // SPARSE_NAV_CORE_BRESENHAM_H
