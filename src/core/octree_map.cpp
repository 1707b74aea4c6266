#include "sparse_nav/core/octree_map.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>
#include <unordered_map>
#include <utility>
#include <vector>
#include <stdexcept>

#include <octomap/OcTree.h>
#include <octomap/octomap.h>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "radix_sort.h"

namespace sparse_nav
{
namespace
{
/// Walks the binary node stream the way OctoMap's readBinaryNode does, but bounded by the tree
/// depth (16) and the end of the data; counts the nodes. OctoMap itself recurses without either
/// bound, so a corrupt file could read uninitialised bytes or overflow the stack.
bool walkBinaryNode(const std::string& data, std::size_t& pos, int depth, std::size_t& n_nodes)
{
  if (depth >= 16 || data.size() - pos < 2)
  {
    return false;
  }
  const unsigned char bytes[2] = { static_cast<unsigned char>(data[pos]), static_cast<unsigned char>(data[pos + 1]) };
  pos += 2;
  bool has_children[8];
  for (int i = 0; i < 8; ++i)
  {
    const unsigned char b = bytes[i / 4];
    const int bit = (i % 4) * 2;
    const bool lo = (b >> bit) & 1U;
    const bool hi = (b >> (bit + 1)) & 1U;
    has_children[i] = lo && hi;
    if (lo || hi)
    {
      ++n_nodes;
    }
  }
  for (int i = 0; i < 8; ++i)
  {
    if (has_children[i] && !walkBinaryNode(data, pos, depth + 1, n_nodes))
    {
      return false;
    }
  }
  return true;
}

bool validateBinaryOctree(const std::string& bytes, std::string* problem)
{
  std::istringstream in(bytes);
  std::string line;
  std::getline(in, line);
  if (line.rfind("# Octomap OcTree binary file", 0) != 0)
  {
    *problem = "the first line is not '# Octomap OcTree binary file'";
    return false;
  }
  std::string id;
  long long size = -1;
  double res = 0.0;
  bool data = false;
  while (std::getline(in, line))
  {
    if (line.empty() || line[0] == '#')
    {
      continue;
    }
    std::istringstream words(line);
    std::string token;
    words >> token;
    if (token == "id")
    {
      words >> id;
    }
    else if (token == "size")
    {
      words >> size;
    }
    else if (token == "res")
    {
      words >> res;
    }
    else if (token == "data")
    {
      data = true;
      break;
    }
    else
    {
      *problem = "unexpected header line '" + line.substr(0, 40) + "'";
      return false;
    }
  }
  if (!data || id.empty() || size < 0 || !(res > 0.0) || !std::isfinite(res))
  {
    *problem = "incomplete header (needs id, size, res and data lines)";
    return false;
  }
  if (id != "OcTree")
  {
    *problem = "tree type '" + id + "' is not OcTree";
    return false;
  }
  const std::streamoff offset = in.tellg();
  std::size_t pos = offset < 0 ? bytes.size() : static_cast<std::size_t>(offset);
  if (size == 0)
  {
    return true;
  }
  std::size_t n_nodes = 1;
  if (!walkBinaryNode(bytes, pos, 0, n_nodes))
  {
    *problem = "the node data is truncated or deeper than 16 levels";
    return false;
  }
  if (static_cast<long long>(n_nodes) != size)
  {
    *problem = "the header declares " + std::to_string(size) + " nodes but the data holds " + std::to_string(n_nodes);
    return false;
  }
  return true;
}
}  // namespace

void OctreeMapConfig::validate() const
{
  if (!(resolution_m > 0.0) || !std::isfinite(resolution_m))
  {
    throw std::invalid_argument("OctreeMapConfig: resolution_m must be finite and > 0");
  }
  if (!std::isfinite(max_range_m))
  {
    throw std::invalid_argument("OctreeMapConfig: max_range_m must be finite (< 0 for no limit)");
  }
  const double ratio = free_space_resolution_m / resolution_m;
  const double levels = std::round(std::log2(ratio));
  if (!std::isfinite(ratio) || levels < 0.0 || levels > 8.0 || std::abs(ratio - std::pow(2.0, levels)) > 1e-6 * ratio)
  {
    throw std::invalid_argument("OctreeMapConfig: free_space_resolution_m must be resolution_m times 1, 2, 4, ... 256");
  }
  if (!(prob_hit > 0.5 && prob_hit < 1.0))
  {
    throw std::invalid_argument("OctreeMapConfig: prob_hit must be in (0.5, 1)");
  }
  if (!(prob_miss > 0.0 && prob_miss < 0.5))
  {
    throw std::invalid_argument("OctreeMapConfig: prob_miss must be in (0, 0.5)");
  }
}

OctreeMap::OctreeMap(const OctreeMapConfig& config) : config_(config)
{
  config_.validate();
  free_levels_ = static_cast<unsigned>(std::lround(std::log2(config_.free_space_resolution_m / config_.resolution_m)));
  resetTree();
}

OctreeMap::~OctreeMap() = default;

void OctreeMap::resetTree()
{
  tree_ = std::make_unique<octomap::OcTree>(config_.resolution_m);
  tree_->setProbHit(config_.prob_hit);
  tree_->setProbMiss(config_.prob_miss);
  inserted_.clear();
}

double OctreeMap::maxCoordinate() const
{
  // Keys are 16 bit around the centre: +-32768 voxels; keep one voxel of margin.
  return (32768.0 - 1.0) * tree_->getResolution();
}

bool OctreeMap::inRange(const Eigen::Vector3d& p) const
{
  const double limit = maxCoordinate();
  return p.allFinite() && std::abs(p.x()) < limit && std::abs(p.y()) < limit && std::abs(p.z()) < limit;
}

OctreeInsertStats OctreeMap::insert(const PointList& points, const Eigen::Vector3d& sensor_origin)
{
  return insert(points, std::vector<Eigen::Vector3d>{ sensor_origin }, std::vector<std::size_t>(points.size(), 0));
}

namespace
{
using Cell = Eigen::Array3i;  // coarse voxel index: fine key >> levels, per axis

std::uint64_t packCell(const Cell& c)
{
  return (static_cast<std::uint64_t>(static_cast<std::uint16_t>(c.x())) << 32) |
         (static_cast<std::uint64_t>(static_cast<std::uint16_t>(c.y())) << 16) |
         static_cast<std::uint64_t>(static_cast<std::uint16_t>(c.z()));
}

/// Spreads the low 16 bits of v three bits apart (bit b to bit 3b).
std::uint64_t spreadBits(std::uint32_t v)
{
  std::uint64_t x = v & 0xffffU;
  x = (x | x << 16) & 0x0000ff0000ffULL;
  x = (x | x << 8) & 0x00f00f00f00fULL;
  x = (x | x << 4) & 0x0c30c30c30c3ULL;
  x = (x | x << 2) & 0x249249249249ULL;
  return x;
}

/// Interleaves the bits of x, y, z (16 bits each) into a Morton code (x lowest).
std::uint64_t mortonCode(std::uint32_t x, std::uint32_t y, std::uint32_t z)
{
  return spreadBits(x) | spreadBits(y) << 1 | spreadBits(z) << 2;
}

/// Marks on coarse voxels: dense over a bounding box when it is small enough, hashed otherwise.
class CellMarks
{
public:
  static constexpr std::uint8_t kRay = 1, kEndpoint = 2;

  // A dense box has a margin of one cell on every side: a segment between two cells of the box
  // steps at most one cell past its end (rounding at a cell corner; the next boundary after that
  // one lies a whole cell further along the segment), so a walk may mark unchecked and the margin,
  // never read, takes such marks.
  CellMarks(const Cell& lo, const Cell& hi) : lo_(lo), size_(hi - lo + 1)
  {
    const double n = (static_cast<double>(size_.x()) + 2) * (size_.y() + 2) * (size_.z() + 2);
    if (n <= 64.0 * 1024 * 1024)
    {
      row_ = size_.x() + 2;
      slice_ = row_ * (size_.y() + 2);
      dense_.assign(static_cast<std::size_t>(n), 0);
    }
  }
  /// Sets bits on c.
  void mark(const Cell& c, std::uint8_t bits)
  {
    if (!inBox(c))
    {
      return;
    }
    (dense_.empty() ? sparse_[packCell(c)] : dense_[index(c)]) |= bits;
  }
  bool isDense() const { return !dense_.empty(); }
  /// A dense box's storage, in copies of its own: a walk's byte stores, which may alias anything,
  /// then do not force the box to be reloaded per cell.
  struct DenseWriter
  {
    Cell lo;
    std::ptrdiff_t row, slice;  // index steps of y and z
    std::uint8_t* data;
    /// The place of c, in the box or its margin.
    std::ptrdiff_t index(const Cell& c) const
    {
      const Cell d = c - lo + 1;
      return d.z() * slice + d.y() * row + d.x();
    }
  };
  /// The writer of a dense box (isDense()); valid while this lives.
  DenseWriter denseWriter() { return DenseWriter{ lo_, row_, slice_, dense_.data() }; }
  /// Calls visit(Morton code) for every cell whose marks are exactly `bits`, in increasing code
  /// order: the order the octree update needs, reached in a dense box by descending its aligned
  /// cubes in Morton order instead of sorting ~10^5 codes afterwards. Cubes whose rows hold no
  /// such cell are skipped whole, so an update that cast a few rays does not walk the whole box.
  template <typename Visit>
  void forEachWithBits(std::uint8_t bits, Visit visit) const
  {
    if (!dense_.empty())
    {
      // Summed-area table over (y, z) of the x-rows that hold a wanted cell.
      const int w = size_.y() + 1;
      std::vector<std::uint32_t> rows(static_cast<std::size_t>(w) * (size_.z() + 1), 0);
      for (int z = 0; z < size_.z(); ++z)
      {
        for (int y = 0; y < size_.y(); ++y)
        {
          const std::uint8_t* row = &dense_[index(lo_ + Cell(0, y, z))];
          const bool any = std::find(row, row + size_.x(), bits) != row + size_.x();
          rows[static_cast<std::size_t>(z + 1) * w + y + 1] = static_cast<std::uint32_t>(any) +
                                                              rows[static_cast<std::size_t>(z) * w + y + 1] +
                                                              rows[static_cast<std::size_t>(z + 1) * w + y] -
                                                              rows[static_cast<std::size_t>(z) * w + y];
        }
      }
      const Cell hi = lo_ + size_ - 1;
      int level = 0;
      while ((lo_.x() >> level) != (hi.x() >> level) || (lo_.y() >> level) != (hi.y() >> level) ||
             (lo_.z() >> level) != (hi.z() >> level))
      {
        ++level;
      }
      const Cell corner(lo_.x() >> level << level, lo_.y() >> level << level, lo_.z() >> level << level);
      visitCube(corner,
                mortonCode(static_cast<std::uint32_t>(corner.x()), static_cast<std::uint32_t>(corner.y()),
                           static_cast<std::uint32_t>(corner.z())),
                level, bits, rows, visit);
      return;
    }
    std::vector<std::uint64_t> codes;
    for (const auto& kv : sparse_)
    {
      if (kv.second == bits)
      {
        codes.push_back(mortonCode(static_cast<std::uint32_t>((kv.first >> 32) & 0xffff),
                                   static_cast<std::uint32_t>((kv.first >> 16) & 0xffff),
                                   static_cast<std::uint32_t>(kv.first & 0xffff)));
      }
    }
    radixSort(codes);
    for (const std::uint64_t code : codes)
    {
      visit(code);
    }
  }

private:
  /// Rounding at a cell corner may step a traversal one cell past the box; such cells are skipped.
  bool inBox(const Cell& c) const
  {
    const Cell d = c - lo_;
    return static_cast<unsigned>(d.x()) < static_cast<unsigned>(size_.x()) &&
           static_cast<unsigned>(d.y()) < static_cast<unsigned>(size_.y()) &&
           static_cast<unsigned>(d.z()) < static_cast<unsigned>(size_.z());
  }
  std::size_t index(const Cell& c) const
  {
    const Cell d = c - lo_ + 1;
    return static_cast<std::size_t>(d.z() * slice_ + d.y() * row_ + d.x());
  }
  /// The cells marked exactly `bits` in the box and in the aligned cube of edge 2^level at corner,
  /// in Morton order (a cube's children in Morton order: x is the lowest bit of the child index).
  /// code: the corner's Morton code, whose low 3 * level bits are 0 (an aligned corner), so that
  /// child i's corner has code | i << 3 * (level - 1). rows: forEachWithBits' summed-area table of
  /// the rows holding such cells.
  template <typename Visit>
  void visitCube(const Cell& corner, std::uint64_t code, int level, std::uint8_t bits,
                 const std::vector<std::uint32_t>& rows, Visit& visit) const
  {
    const Cell d = corner - lo_;
    const int edge = 1 << level;
    if (((d + edge) <= 0).any() || (d >= size_).any())
    {
      return;
    }
    const int y0 = std::max(0, d.y()), y1 = std::min(size_.y(), d.y() + edge);
    const int z0 = std::max(0, d.z()), z1 = std::min(size_.z(), d.z() + edge);
    const std::size_t w = static_cast<std::size_t>(size_.y()) + 1;
    if (rows[z1 * w + y1] - rows[z0 * w + y1] - rows[z1 * w + y0] + rows[z0 * w + y0] == 0)
    {
      return;
    }
    if (level <= 1)
    {
      for (int i = 0; i < (level == 1 ? 8 : 1); ++i)
      {
        const Cell c(corner.x() + (i & 1), corner.y() + ((i >> 1) & 1), corner.z() + (i >> 2));
        if (inBox(c) && dense_[index(c)] == bits)
        {
          visit(code | static_cast<std::uint64_t>(i));
        }
      }
      return;
    }
    const int half = edge / 2;
    for (int i = 0; i < 8; ++i)
    {
      visitCube(Cell(corner.x() + (i & 1) * half, corner.y() + ((i >> 1) & 1) * half, corner.z() + (i >> 2) * half),
                code | static_cast<std::uint64_t>(i) << (3 * (level - 1)), level - 1, bits, rows, visit);
    }
  }
  Cell lo_, size_;
  std::ptrdiff_t row_ = 0, slice_ = 0;  // dense: index steps of y and z, margin included
  std::vector<std::uint8_t> dense_;
  std::unordered_map<std::uint64_t, std::uint8_t> sparse_;
};

/// The coarse cells on the segment from a to b (metres), Amanatides-Woo: the cell of a, one more
/// per step, and the cell of b only when include_end. Cells are `size` metres, cell i starting at
/// (i - offset) * size.
struct Segment
{
  Cell cell;       // the current cell
  Cell step;       // per axis: +1, -1, or 0 when it does not move
  Cell end;        // the cell of b
  double t[3];     // per axis: where along the segment (0 at a, 1 at b) its next boundary lies
  double dt[3];    // ... and the distance between its boundaries
  int remaining;   // steps left
  bool include_end;

  Segment(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Cell& ca, const Cell& cb, double size, int offset,
          bool include)
    : cell(ca), step(Cell::Zero()), end(cb), remaining((cb - ca).abs().sum()), include_end(include)
  {
    const Eigen::Vector3d d = b - a;
    for (int i = 0; i < 3; ++i)
    {
      step[i] = cb[i] > ca[i] ? 1 : (cb[i] < ca[i] ? -1 : 0);
      if (step[i] == 0 || d[i] == 0.0)
      {
        step[i] = 0;
        t[i] = dt[i] = std::numeric_limits<double>::infinity();
        continue;
      }
      const double boundary = (static_cast<double>(ca[i] - offset) + (step[i] > 0 ? 1.0 : 0.0)) * size;
      t[i] = (boundary - a[i]) / d[i];
      dt[i] = size / std::abs(d[i]);
    }
  }
  /// One step: the axis whose boundary comes first moves (x before y before z on a tie).
  void advance()
  {
    const bool sx = t[0] <= t[1] && t[0] <= t[2];
    const bool sy = !sx && t[1] <= t[2];
    const bool sz = !sx && !sy;
    cell[0] += sx ? step[0] : 0;
    cell[1] += sy ? step[1] : 0;
    cell[2] += sz ? step[2] : 0;
    t[0] += sx ? dt[0] : 0.0;
    t[1] += sy ? dt[1] : 0.0;
    t[2] += sz ? dt[2] : 0.0;
    --remaining;
  }
  /// Whether the cell reached by the last step is one of the segment's.
  bool endsInCell() const { return include_end || (cell != end).any(); }
};

/// Visits the cells of a segment.
template <typename Visit>
void traverse(Segment s, Visit visit)
{
  for (; s.remaining > 0; s.advance())
  {
    visit(s.cell);
  }
  if (s.endsInCell())
  {
    visit(s.cell);
  }
}

/// Sets bits on the cells of each segment in a dense box. One segment's steps each wait on the
/// last (compare, select, add), most of each step on a single segment; with SSE2 two segments
/// step at once in the lanes of vectors, their cells' places kept as indices (marked unchecked:
/// the box's margin holds any cell past an end), until one ends and the next takes its lane.
void markSegments(const std::vector<Segment>& segments, const CellMarks::DenseWriter& box, std::uint8_t bits)
{
  std::size_t next = 0;
#if defined(__SSE2__)
  if (segments.size() >= 2)
  {
    Segment lanes[2] = { segments[0], segments[1] };
    next = 2;
    while (true)
    {
      const Segment& a = lanes[0];
      const Segment& b = lanes[1];
      const int steps = std::min(a.remaining, b.remaining);
      __m128d t0 = _mm_set_pd(b.t[0], a.t[0]), t1 = _mm_set_pd(b.t[1], a.t[1]), t2 = _mm_set_pd(b.t[2], a.t[2]);
      const __m128d dt0 = _mm_set_pd(b.dt[0], a.dt[0]), dt1 = _mm_set_pd(b.dt[1], a.dt[1]), dt2 = _mm_set_pd(b.dt[2], a.dt[2]);
      const __m128i step_x = _mm_set_epi64x(b.step[0], a.step[0]);
      const __m128i step_y = _mm_set_epi64x(b.step[1] * box.row, a.step[1] * box.row);
      const __m128i step_z = _mm_set_epi64x(b.step[2] * box.slice, a.step[2] * box.slice);
      const __m128i all = _mm_set1_epi32(-1);
      __m128i at = _mm_set_epi64x(box.index(b.cell), box.index(a.cell));
      for (int s = 0; s < steps; ++s)
      {
        box.data[_mm_cvtsi128_si64(at)] |= bits;
        box.data[_mm_cvtsi128_si64(_mm_unpackhi_epi64(at, at))] |= bits;
        const __m128d x01 = _mm_cmple_pd(t0, t1), x02 = _mm_cmple_pd(t0, t2), y12 = _mm_cmple_pd(t1, t2);
        const __m128d sx = _mm_and_pd(x01, x02);
        const __m128d sy = _mm_andnot_pd(sx, y12);
        const __m128d sz = _mm_andnot_pd(_mm_or_pd(sx, y12), _mm_castsi128_pd(all));
        t0 = _mm_add_pd(t0, _mm_and_pd(sx, dt0));
        t1 = _mm_add_pd(t1, _mm_and_pd(sy, dt1));
        t2 = _mm_add_pd(t2, _mm_and_pd(sz, dt2));
        at = _mm_add_epi64(at, _mm_add_epi64(_mm_and_si128(_mm_castpd_si128(sx), step_x),
                                             _mm_add_epi64(_mm_and_si128(_mm_castpd_si128(sy), step_y),
                                                           _mm_and_si128(_mm_castpd_si128(sz), step_z))));
      }
      alignas(16) double t[3][2];
      alignas(16) std::int64_t index[2];
      _mm_store_pd(t[0], t0);
      _mm_store_pd(t[1], t1);
      _mm_store_pd(t[2], t2);
      _mm_store_si128(reinterpret_cast<__m128i*>(index), at);
      bool refilled = true;
      for (int l = 0; l < 2; ++l)
      {
        Segment& lane = lanes[l];
        for (int i = 0; i < 3; ++i)
        {
          lane.t[i] = t[i][l];
        }
        // Back from the index to the cell: each axis moved only in its step's direction.
        const std::int64_t z = index[l] / box.slice, y = index[l] % box.slice / box.row, x = index[l] % box.row;
        lane.cell = box.lo + Cell(static_cast<int>(x), static_cast<int>(y), static_cast<int>(z)) - 1;
        lane.remaining -= steps;
        if (lane.remaining > 0)
        {
          continue;
        }
        if (lane.endsInCell())
        {
          box.data[index[l]] |= bits;
        }
        if (next == segments.size())
        {
          refilled = false;
          lane.remaining = -1;
        }
        else
        {
          lane = segments[next++];
        }
      }
      if (!refilled)
      {
        for (const Segment& rest : lanes)
        {
          if (rest.remaining >= 0)
          {
            traverse(rest, [&box, bits](const Cell& c) { box.data[box.index(c)] |= bits; });
          }
        }
        return;
      }
    }
  }
#endif
  for (; next < segments.size(); ++next)
  {
    traverse(segments[next], [&box, bits](const Cell& c) { box.data[box.index(c)] |= bits; });
  }
}

/// Applies a log-odds update to every leaf under node; unknown children become free leaves.
void updateSubtree(octomap::OcTree& tree, octomap::OcTreeNode* node, unsigned depth, float log_odds)
{
  if (depth >= tree.getTreeDepth() || !tree.nodeHasChildren(node))
  {
    tree.updateNodeLogOdds(node, log_odds);
    return;
  }
  for (unsigned i = 0; i < 8; ++i)
  {
    if (tree.nodeChildExists(node, i))
    {
      updateSubtree(tree, tree.getNodeChild(node, i), depth + 1, log_odds);
    }
    else
    {
      tree.updateNodeLogOdds(tree.createNodeChild(node, i), log_odds);
    }
  }
  node->updateOccupancyChildren();
}

/// A log-odds update of the node at `depth` whose fine key has Morton code `code`.
struct NodeUpdate
{
  std::uint64_t code;
  unsigned depth;
  float log_odds;
  bool operator<(const NodeUpdate& o) const { return code < o.code; }
};

/// Applies updates sorted by code, covering disjoint subtrees of node, in one descent: each node
/// on their paths is visited once (a pruned leaf is expanded, a missing child created) and its
/// occupancy refreshed from its children after theirs, which is what OctoMap's lazy updateNode
/// plus updateInnerOccupancy give, without walking from the root once per update.
void applySorted(octomap::OcTree& tree, octomap::OcTreeNode* node, bool just_created, unsigned depth,
                 const NodeUpdate* first, const NodeUpdate* last)
{
  if (last - first == 1 && first->depth == depth)
  {
    updateSubtree(tree, node, depth, first->log_odds);
    return;
  }
  const unsigned shift = 3 * (tree.getTreeDepth() - 1 - depth);
  if (!tree.nodeHasChildren(node) && !just_created)
  {
    tree.expandNode(node);  // a pruned leaf: its children inherit its value
  }
  while (first != last)
  {
    const unsigned pos = static_cast<unsigned>((first->code >> shift) & 7U);
    const NodeUpdate* end = first;
    while (end != last && ((end->code >> shift) & 7U) == pos)
    {
      ++end;
    }
    bool created = false;
    if (!tree.nodeChildExists(node, pos))
    {
      tree.createNodeChild(node, pos);
      created = true;
    }
    applySorted(tree, tree.getNodeChild(node, pos), created, depth + 1, first, end);
    first = end;
  }
  node->updateOccupancyChildren();
}
}  // namespace

OctreeInsertStats OctreeMap::insert(const PointList& points, const std::vector<Eigen::Vector3d>& origins,
                                    const std::vector<std::size_t>& origin_of_point, const PointList* also_held)
{
  OctreeInsertStats stats;
  if (origin_of_point.size() != points.size())
  {
    throw std::invalid_argument("OctreeMap::insert: origin_of_point must have one entry per point");
  }
  std::vector<char> origin_ok(origins.size(), 0);
  for (std::size_t c = 0; c < origins.size(); ++c)
  {
    origin_ok[c] = inRange(origins[c]) ? 1 : 0;
  }
  if (std::find(origin_ok.begin(), origin_ok.end(), 1) == origin_ok.end())
  {
    stats.origin_ok = false;
    stats.n_out_of_range = points.size();
    return stats;
  }
  const unsigned levels = free_levels_;
  const double coarse = config_.resolution_m * static_cast<double>(1U << levels);
  const int offset = 32768 >> levels;
  const double max_range = config_.max_range_m;
  auto cellOf = [&](const octomap::OcTreeKey& k) { return Cell(k[0] >> levels, k[1] >> levels, k[2] >> levels); };
  auto centreOf = [&](const Cell& c) {
    return Eigen::Vector3d((c.x() - offset + 0.5) * coarse, (c.y() - offset + 0.5) * coarse,
                           (c.z() - offset + 0.5) * coarse);
  };

  // Endpoints: new fine voxels become hits; every endpoint's coarse voxel is kept from being freed.
  struct Endpoint
  {
    octomap::OcTreeKey key;
    Cell cell;
    std::size_t origin;
    bool is_new;
  };
  std::vector<Endpoint> endpoints;
  endpoints.reserve(points.size());
  Cell lo = Cell::Constant(std::numeric_limits<int>::max()), hi = Cell::Constant(std::numeric_limits<int>::lowest());
  std::vector<Cell> origin_cells(origins.size(), Cell::Zero());
  for (std::size_t c = 0; c < origins.size(); ++c)
  {
    if (origin_ok[c])
    {
      origin_cells[c] = cellOf(tree_->coordToKey(origins[c].x(), origins[c].y(), origins[c].z()));
      lo = lo.min(origin_cells[c]);
      hi = hi.max(origin_cells[c]);
    }
  }
  // A later cloud mostly repeats the voxels of the earlier ones: room for this one's is enough.
  inserted_.reserve(std::max(inserted_.size(), points.size()));
  for (std::size_t i = 0; i < points.size(); ++i)
  {
    const Eigen::Vector3d p = points[i].cast<double>();
    const std::size_t o = origin_of_point[i];
    if (o >= origins.size() || !origin_ok[o] || !inRange(p))
    {
      ++stats.n_out_of_range;
      continue;
    }
    Endpoint e;
    e.key = tree_->coordToKey(p.x(), p.y(), p.z());
    e.cell = cellOf(e.key);
    e.origin = o;
    e.is_new = false;
    endpoints.push_back(e);
    lo = lo.min(e.cell);
    hi = hi.max(e.cell);
  }
  // The seen-voxel lookups, in the same order, with the slot of the lookup kAhead later fetched
  // meanwhile: the table (megabytes) is probed at random, and each probe otherwise waited on a
  // cache miss (~4 ms of 10^5 lookups).
  constexpr std::size_t kAhead = 16;
  auto packKey = [](const octomap::OcTreeKey& k) {
    return (static_cast<std::uint64_t>(k[0]) << 32) | (static_cast<std::uint64_t>(k[1]) << 16) | k[2];
  };
  for (std::size_t i = 0; i < endpoints.size(); ++i)
  {
    if (i + kAhead < endpoints.size())
    {
      inserted_.prefetch(packKey(endpoints[i + kAhead].key));
    }
    endpoints[i].is_new = inserted_.insert(packKey(endpoints[i].key));
  }
  stats.n_inserted = endpoints.size();
  if (endpoints.empty())
  {
    return stats;
  }
  // The coarse voxels of the points held from before (in range when they were inserted) lie
  // between those of their coordinates' extremes: a key grows with its coordinate.
  auto heldInRange = [&](auto visit) {
    if (also_held)
    {
      for (const auto& q : *also_held)
      {
        const Eigen::Vector3d p = q.cast<double>();
        if (inRange(p))
        {
          visit(p);
        }
      }
    }
  };
  Eigen::Vector3d held_lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), held_hi = -held_lo;
  heldInRange([&](const Eigen::Vector3d& p) {
    held_lo = held_lo.cwiseMin(p);
    held_hi = held_hi.cwiseMax(p);
  });
  if (held_lo.x() <= held_hi.x())
  {
    lo = lo.min(cellOf(tree_->coordToKey(held_lo.x(), held_lo.y(), held_lo.z())));
    hi = hi.max(cellOf(tree_->coordToKey(held_hi.x(), held_hi.y(), held_hi.z())));
  }

  CellMarks marks(lo, hi);
  for (const auto& e : endpoints)
  {
    marks.mark(e.cell, CellMarks::kEndpoint);
  }
  heldInRange([&](const Eigen::Vector3d& p) { marks.mark(cellOf(tree_->coordToKey(p.x(), p.y(), p.z())), CellMarks::kEndpoint); });
  // Rays in a dense box are walked in batches, two at a time (markSegments).
  std::vector<Segment> batch;
  auto castRay = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Cell& ca, const Cell& cb,
                     bool include_end) {
    const Segment segment(a, b, ca, cb, coarse, offset, include_end);
    if (!marks.isDense())
    {
      traverse(segment, [&](const Cell& c) { marks.mark(c, CellMarks::kRay); });
      return;
    }
    batch.push_back(segment);
    if (batch.size() == 1024)
    {
      markSegments(batch, marks.denseWriter(), CellMarks::kRay);
      batch.clear();
    }
  };
  // One ray per (camera, coarse endpoint voxel) among the new endpoints, to the voxel's centre.
  FlatKeySet cast;
  std::vector<std::uint64_t> hit_codes;  // Morton codes of the new endpoint voxels to mark as hits
  octomap::OcTreeKey first_hit;
  for (const auto& e : endpoints)
  {
    if (!e.is_new)
    {
      continue;
    }
    ++stats.n_new_voxels;
    const Eigen::Vector3d& origin = origins[e.origin];
    const Eigen::Vector3d end = centreOf(e.cell);
    const bool in_range = max_range < 0.0 || (end - origin).norm() <= max_range;
    if (in_range)
    {
      if (hit_codes.empty())
      {
        first_hit = e.key;
      }
      hit_codes.push_back(mortonCode(e.key[0], e.key[1], e.key[2]));
    }
    if (!cast.insert(packCell(e.cell) ^ (static_cast<std::uint64_t>(e.origin) << 48)))
    {
      continue;
    }
    ++stats.n_rays;
    if (in_range)
    {
      castRay(origin, end, origin_cells[e.origin], e.cell, false);
    }
    else
    {
      const Eigen::Vector3d stop = origin + (end - origin).normalized() * max_range;
      const Cell cs = cellOf(tree_->coordToKey(stop.x(), stop.y(), stop.z()));
      if (((cs - lo) >= 0).all() && ((hi - cs) >= 0).all())
      {
        castRay(origin, stop, origin_cells[e.origin], cs, true);
      }
    }
  }
  if (!batch.empty())
  {
    markSegments(batch, marks.denseWriter(), CellMarks::kRay);
  }
  const float hit = tree_->getProbHitLog();
  const unsigned tree_depth = tree_->getTreeDepth();
  if (!tree_->getRoot() && !hit_codes.empty())
  {
    // The first insertion needs a root, which only OctoMap's own updateNode can create.
    tree_->updateNode(first_hit, hit, false);
    hit_codes.front() = hit_codes.back();
    hit_codes.pop_back();
  }
  // Radix sort of the bare codes: ~10^5 keys per insertion, where std::sort cost milliseconds, and
  // sorting 16-byte updates through a key functor twice as long.
  radixSort(hit_codes);
  std::vector<NodeUpdate> updates;
  updates.reserve(hit_codes.size());
  for (const std::uint64_t code : hit_codes)
  {
    updates.push_back(NodeUpdate{ code, tree_depth, hit });
  }
  if (tree_->getRoot())
  {
    const float miss = tree_->getProbMissLog();
    const unsigned target_depth = tree_depth - levels;
    // Free cells in Morton order; an aligned run of 8^k consecutive codes is a whole octree node
    // k levels above the coarse leaves, updated once (most of a room's volume is such blocks).
    // Free cells never share a coarse voxel with an endpoint, so no two updates overlap.
    const std::size_t n_hits = updates.size();
    std::vector<std::uint64_t> free_cells;
    marks.forEachWithBits(CellMarks::kRay, [&](std::uint64_t code) { free_cells.push_back(code); });
    stats.n_free_voxels = free_cells.size();
    for (std::size_t i = 0; i < free_cells.size();)
    {
      const std::uint64_t code = free_cells[i];
      unsigned up = 0;
      while (up < target_depth)
      {
        const std::uint64_t span = std::uint64_t{ 1 } << (3 * (up + 1));
        if ((code & (span - 1)) != 0 || i + span > free_cells.size() || free_cells[i + span - 1] != code + span - 1)
        {
          break;
        }
        ++up;
      }
      updates.push_back(NodeUpdate{ code << (3 * levels), target_depth - up, miss });
      i += std::size_t{ 1 } << (3 * up);
    }
    std::inplace_merge(updates.begin(), updates.begin() + static_cast<std::ptrdiff_t>(n_hits), updates.end());
    if (!updates.empty())
    {
      applySorted(*tree_, tree_->getRoot(), false, 0, updates.data(), updates.data() + updates.size());
    }
  }
  return stats;
}

VoxelState OctreeMap::query(const Eigen::Vector3d& position) const
{
  if (!inRange(position))
  {
    return VoxelState::kUnknown;
  }
  const octomap::OcTreeNode* node = tree_->search(position.x(), position.y(), position.z());
  if (!node)
  {
    return VoxelState::kUnknown;
  }
  return tree_->isNodeOccupied(node) ? VoxelState::kOccupied : VoxelState::kFree;
}

std::vector<VoxelState> OctreeMap::query(const PointList& positions) const
{
  std::vector<VoxelState> states(positions.size(), VoxelState::kUnknown);
  const octomap::OcTreeNode* root = tree_->getRoot();
  if (!root)
  {
    return states;
  }
  // (Morton code of the fine key, position index) of the positions search() would find a key for.
  std::vector<std::pair<std::uint64_t, std::uint32_t>> order;
  order.reserve(positions.size());
  for (std::size_t i = 0; i < positions.size(); ++i)
  {
    const Eigen::Vector3d p = positions[i].cast<double>();
    octomap::OcTreeKey k;
    if (inRange(p) && tree_->coordToKeyChecked(p.x(), p.y(), p.z(), k))
    {
      order.emplace_back(mortonCode(k[0], k[1], k[2]), static_cast<std::uint32_t>(i));
    }
  }
  radixSortBy(order, [](const std::pair<std::uint64_t, std::uint32_t>& o) { return o.first; });
  // OcTree::search(key) walks from the root, taking child (code >> 3 * level) & 7 at each level
  // from the top; path[s] is the node after s steps of the previous walk, which took `reached`.
  const unsigned depth = tree_->getTreeDepth();
  std::vector<const octomap::OcTreeNode*> path(depth + 1, nullptr);
  path[0] = root;
  unsigned reached = 0;
  std::uint64_t previous = 0;
  for (const auto& o : order)
  {
    const std::uint64_t code = o.first;
    unsigned shared = depth;  // leading 3-bit child indices equal to the previous code's
    if (code != previous)
    {
      const int top = 63 - __builtin_clzll(code ^ previous);
      shared = depth - 1 - static_cast<unsigned>(top) / 3;
    }
    unsigned step = std::min(shared, reached);
    const octomap::OcTreeNode* found = nullptr;
    for (; step < depth; ++step)
    {
      const octomap::OcTreeNode* node = path[step];
      const unsigned pos = static_cast<unsigned>((code >> (3 * (depth - 1 - step))) & 7U);
      if (!tree_->nodeChildExists(node, pos))
      {
        found = tree_->nodeHasChildren(node) ? nullptr : node;
        break;
      }
      path[step + 1] = tree_->getNodeChild(node, pos);
    }
    if (step == depth)
    {
      found = path[depth];
    }
    reached = step;
    previous = code;
    if (found)
    {
      states[o.second] = tree_->isNodeOccupied(found) ? VoxelState::kOccupied : VoxelState::kFree;
    }
  }
  return states;
}

PointList OctreeMap::occupiedCenters() const
{
  PointList out;
  for (auto it = tree_->begin_leafs(), end = tree_->end_leafs(); it != end; ++it)
  {
    if (tree_->isNodeOccupied(*it))
    {
      out.emplace_back(it.getX(), it.getY(), it.getZ());
    }
  }
  return out;
}

void OctreeMap::markFreeColumns(double origin_x_m, double origin_y_m, double resolution_m, int width, int height,
                                double z_min_m, double z_max_m, std::vector<std::uint8_t>& free_mask) const
{
  if (width <= 0 || height <= 0 || tree_->size() == 0)
  {
    return;
  }
  free_mask.resize(static_cast<std::size_t>(width) * height, 0);
  std::vector<std::uint8_t> occupied(free_mask.size(), 0);
  const double limit = maxCoordinate();
  auto clampc = [limit](double v) { return std::max(-limit, std::min(limit, v)); };
  const octomap::point3d lo(static_cast<float>(clampc(origin_x_m)), static_cast<float>(clampc(origin_y_m)),
                            static_cast<float>(clampc(z_min_m)));
  const octomap::point3d hi(static_cast<float>(clampc(origin_x_m + width * resolution_m)),
                            static_cast<float>(clampc(origin_y_m + height * resolution_m)),
                            static_cast<float>(clampc(z_max_m)));
  for (auto it = tree_->begin_leafs_bbx(lo, hi), end = tree_->end_leafs_bbx(); it != end; ++it)
  {
    const double half = 0.5 * it.getSize();
    const double cz = it.getZ();
    if (cz + half < z_min_m || cz - half > z_max_m)
    {
      continue;
    }
    const bool occ = tree_->isNodeOccupied(*it);
    // Cells whose centre lies inside the leaf's footprint.
    const int c0 = std::max(0, static_cast<int>(std::ceil((it.getX() - half - origin_x_m) / resolution_m - 0.5)));
    const int c1 = std::min(width - 1, static_cast<int>(std::floor((it.getX() + half - origin_x_m) / resolution_m - 0.5)));
    const int r0 = std::max(0, static_cast<int>(std::ceil((it.getY() - half - origin_y_m) / resolution_m - 0.5)));
    const int r1 = std::min(height - 1, static_cast<int>(std::floor((it.getY() + half - origin_y_m) / resolution_m - 0.5)));
    for (int r = r0; r <= r1; ++r)
    {
      for (int c = c0; c <= c1; ++c)
      {
        const std::size_t i = static_cast<std::size_t>(r) * width + c;
        if (occ)
        {
          occupied[i] = 1;
        }
        else
        {
          free_mask[i] = 1;
        }
      }
    }
  }
  for (std::size_t i = 0; i < free_mask.size(); ++i)
  {
    if (occupied[i])
    {
      free_mask[i] = 0;
    }
  }
}

std::size_t OctreeMap::numLeafNodes() const
{
  return tree_->getNumLeafNodes();
}

void OctreeMap::clear()
{
  resetTree();
}

IoStatus OctreeMap::save(const std::string& path) const
{
  IoStatus status;
  try
  {
    std::ofstream out(path.c_str(), std::ios_base::out | std::ios_base::binary);
    if (!out.is_open())
    {
      status.message = "cannot open '" + path + "' for writing";
      return status;
    }
    if (!tree_->writeBinaryConst(out) || !out.good())
    {
      status.message = "writing the octree to '" + path + "' failed";
      return status;
    }
    status.ok = true;
  }
  catch (const std::exception& e)
  {
    status.message = "writing the octree to '" + path + "' failed: " + e.what();
  }
  catch (...)
  {
    status.message = "writing the octree to '" + path + "' failed";
  }
  return status;
}

IoStatus OctreeMap::load(const std::string& path)
{
  IoStatus status;
  try
  {
    std::ifstream in(path.c_str(), std::ios_base::in | std::ios_base::binary);
    if (!in.is_open())
    {
      status.message = "cannot open '" + path + "' for reading";
      return status;
    }
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::string problem;
    if (!validateBinaryOctree(bytes, &problem))
    {
      status.message = "'" + path + "' is not a valid OctoMap .bt file: " + problem;
      return status;
    }
    std::istringstream stream(bytes);
    auto fresh = std::make_unique<octomap::OcTree>(config_.resolution_m);
    fresh->setProbHit(config_.prob_hit);
    fresh->setProbMiss(config_.prob_miss);
    if (!fresh->readBinary(stream))
    {
      status.message = "'" + path + "' is a corrupt OctoMap .bt file (OctoMap refused it)";
      return status;
    }
    tree_ = std::move(fresh);
    // The loaded tree's endpoints are unknown: points inserted later all count as new.
    inserted_.clear();
    status.ok = true;
  }
  catch (const std::exception& e)
  {
    status.message = "'" + path + "' could not be read as an OctoMap .bt file: " + e.what();
  }
  catch (...)
  {
    status.message = "'" + path + "' could not be read as an OctoMap .bt file";
  }
  return status;
}

}  // namespace sparse_nav
