#include "sparse_nav/core/octree_map.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <fstream>
#include <iterator>
#include <sstream>
#include <stdexcept>

#include <octomap/OcTree.h>
#include <octomap/octomap.h>

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
  tree_ = std::make_unique<octomap::OcTree>(config_.resolution_m);
  tree_->setProbHit(config_.prob_hit);
  tree_->setProbMiss(config_.prob_miss);
}

OctreeMap::~OctreeMap() = default;

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
  OctreeInsertStats stats;
  if (!inRange(sensor_origin))
  {
    stats.origin_ok = false;
    stats.n_out_of_range = points.size();
    return stats;
  }
  octomap::Pointcloud cloud;
  cloud.reserve(points.size());
  for (const auto& p : points)
  {
    if (!inRange(p.cast<double>()))
    {
      ++stats.n_out_of_range;
      continue;
    }
    cloud.push_back(p.x(), p.y(), p.z());
  }
  stats.n_inserted = cloud.size();
  const octomap::point3d origin(static_cast<float>(sensor_origin.x()), static_cast<float>(sensor_origin.y()),
                                static_cast<float>(sensor_origin.z()));
  tree_->insertPointCloud(cloud, origin, config_.max_range_m, false, true);
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
  tree_->clear();
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
