// octomap_peer: the octomap_server way of turning a point cloud into a 2D map, timed, as a peer
// for bench/bench_grid.py. Not part of the package.
//
//   octomap_peer FILE --resolution R --min-z Z0 --max-z Z1 [--origin X Y Z] [--max-range M]
//
// FILE holds x, y, z per line (CSV or whitespace, an optional header line of words), z up, in
// metres. The cloud is inserted into an OcTree with OcTree::insertPointCloud from the sensor
// origin (free space ray-cast, octomap_server's default sensor model), the tree is pruned (its
// compress_map default), and the projected map is built as octomap_server's publishAll() and
// update2DMap() do: every leaf whose extent overlaps (Z0, Z1) marks its cells, occupied leaves
// 100, free leaves 0 where still unknown, everything else -1. octomap_server's markers and point
// cloud outputs are not built, so this peer is, if anything, faster than octomap_server itself.
//
// Prints one JSON line: {"n_points", "stages_ms": {"read", "insert", "prune", "project"},
// "total_ms", "grid": {"width", "height", "occupied", "free", "unknown", "leaves"}}.
// Exit status: 0 ok, 2 bad arguments or unreadable file.

#include <octomap/octomap.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

namespace
{
const char* const kUsage =
    "usage: octomap_peer FILE --resolution R --min-z Z0 --max-z Z1 [--origin X Y Z] [--max-range M]\n";

struct Args
{
  std::string file;
  double resolution = 0.05;
  double min_z = -1e9;
  double max_z = 1e9;
  double max_range = -1.0;  // octomap_server's default: unlimited
  octomap::point3d origin{0.0f, 0.0f, 0.0f};
};

double number(const char* flag, const char* text)
{
  char* end = nullptr;
  const double v = std::strtod(text, &end);
  if (end == text || *end != '\0' || !std::isfinite(v))
  {
    throw std::invalid_argument(std::string(flag) + " needs a number, got '" + text + "'");
  }
  return v;
}

Args parseArgs(int argc, char** argv)
{
  Args a;
  for (int i = 1; i < argc; ++i)
  {
    const std::string arg = argv[i];
    auto next = [&]() -> const char* {
      if (i + 1 >= argc)
      {
        throw std::invalid_argument(arg + " needs a value");
      }
      return argv[++i];
    };
    if (arg == "-h" || arg == "--help")
    {
      std::cout << kUsage;
      std::exit(0);
    }
    else if (arg == "--resolution")
      a.resolution = number("--resolution", next());
    else if (arg == "--min-z")
      a.min_z = number("--min-z", next());
    else if (arg == "--max-z")
      a.max_z = number("--max-z", next());
    else if (arg == "--max-range")
      a.max_range = number("--max-range", next());
    else if (arg == "--origin")
    {
      const double x = number("--origin", next());
      const double y = number("--origin", next());
      const double z = number("--origin", next());
      a.origin = octomap::point3d(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
    }
    else if (!arg.empty() && arg[0] == '-' && arg.size() > 1 && !std::isdigit(static_cast<unsigned char>(arg[1])))
      throw std::invalid_argument("unknown option " + arg);
    else if (a.file.empty())
      a.file = arg;
    else
      throw std::invalid_argument("more than one input file");
  }
  if (a.file.empty())
  {
    throw std::invalid_argument("no input FILE given");
  }
  if (!(a.resolution > 0.0) || !(a.max_z > a.min_z))
  {
    throw std::invalid_argument("--resolution must be positive and --max-z above --min-z");
  }
  return a;
}

/// Reads x, y, z per line; a first line that does not start with a number is a header.
bool readPoints(const std::string& path, octomap::Pointcloud& cloud, std::string& error)
{
  std::ifstream in(path.c_str());
  if (!in)
  {
    error = "cannot open " + path;
    return false;
  }
  std::string line;
  std::size_t number_of_line = 0;
  while (std::getline(in, line))
  {
    ++number_of_line;
    for (char& c : line)
    {
      if (c == ',' || c == ';' || c == '\t')
        c = ' ';
    }
    const char* p = line.c_str();
    double v[3];
    int got = 0;
    for (; got < 3; ++got)
    {
      char* end = nullptr;
      v[got] = std::strtod(p, &end);
      if (end == p)
        break;
      p = end;
    }
    if (got == 0 && line.find_first_not_of(' ') == std::string::npos)
      continue;
    if (got < 3)
    {
      if (number_of_line == 1)
        continue;  // header
      error = path + ": line " + std::to_string(number_of_line) + " has fewer than 3 numbers";
      return false;
    }
    if (std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]))
    {
      cloud.push_back(static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2]));
    }
  }
  return true;
}

double msSince(std::chrono::steady_clock::time_point t0)
{
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

int main(int argc, char** argv)
{
  Args args;
  try
  {
    args = parseArgs(argc, argv);
  }
  catch (const std::exception& e)
  {
    std::cerr << "octomap_peer: " << e.what() << "\n" << kUsage;
    return 2;
  }

  auto t0 = std::chrono::steady_clock::now();
  octomap::Pointcloud cloud;
  std::string error;
  if (!readPoints(args.file, cloud, error))
  {
    std::cerr << "octomap_peer: " << error << "\n";
    return 2;
  }
  const double read_ms = msSince(t0);

  t0 = std::chrono::steady_clock::now();
  octomap::OcTree tree(args.resolution);
  tree.insertPointCloud(cloud, args.origin, args.max_range, false, false);
  const double insert_ms = msSince(t0);

  t0 = std::chrono::steady_clock::now();
  tree.prune();
  const double prune_ms = msSince(t0);

  // Projected map as octomap_server: the grid spans the tree's keys from min to max.
  t0 = std::chrono::steady_clock::now();
  double min_x, min_y, min_z, max_x, max_y, max_z;
  tree.getMetricMin(min_x, min_y, min_z);
  tree.getMetricMax(max_x, max_y, max_z);
  const unsigned max_depth = tree.getTreeDepth();
  const octomap::OcTreeKey min_key = tree.coordToKey(octomap::point3d(min_x, min_y, min_z), max_depth);
  const octomap::OcTreeKey max_key = tree.coordToKey(octomap::point3d(max_x, max_y, max_z), max_depth);
  const int width = static_cast<int>(max_key[0]) - static_cast<int>(min_key[0]) + 1;
  const int height = static_cast<int>(max_key[1]) - static_cast<int>(min_key[1]) + 1;
  std::vector<std::int8_t> grid(static_cast<std::size_t>(width) * height, -1);
  auto mark = [&](int i, int j, bool occupied) {
    if (i < 0 || j < 0 || i >= width || j >= height)
      return;
    std::int8_t& cell = grid[static_cast<std::size_t>(j) * width + i];
    if (occupied)
      cell = 100;
    else if (cell == -1)
      cell = 0;
  };
  std::size_t leaves = 0;
  for (auto it = tree.begin_leafs(max_depth), end = tree.end_leafs(); it != end; ++it)
  {
    ++leaves;
    const double z = it.getZ();
    const double half = it.getSize() / 2.0;
    if (!(z + half > args.min_z && z - half < args.max_z))
      continue;
    const bool occupied = tree.isNodeOccupied(*it);
    if (it.getDepth() == max_depth)
    {
      const octomap::OcTreeKey key = it.getKey();
      mark(key[0] - min_key[0], key[1] - min_key[1], occupied);
    }
    else
    {
      const int size = 1 << (max_depth - it.getDepth());
      const octomap::OcTreeKey key = it.getIndexKey();
      for (int dx = 0; dx < size; ++dx)
      {
        for (int dy = 0; dy < size; ++dy)
        {
          mark(key[0] + dx - min_key[0], key[1] + dy - min_key[1], occupied);
        }
      }
    }
  }
  const double project_ms = msSince(t0);

  std::size_t occupied = 0, free_cells = 0;
  for (std::int8_t v : grid)
  {
    occupied += v == 100;
    free_cells += v == 0;
  }
  std::printf(
      "{\"n_points\": %zu, \"stages_ms\": {\"read\": %.3f, \"insert\": %.3f, \"prune\": %.3f, \"project\": %.3f}, "
      "\"total_ms\": %.3f, \"grid\": {\"width\": %d, \"height\": %d, \"occupied\": %zu, \"free\": %zu, "
      "\"unknown\": %zu, \"leaves\": %zu}}\n",
      cloud.size(), read_ms, insert_ms, prune_ms, project_ms, read_ms + insert_ms + prune_ms + project_ms, width,
      height, occupied, free_cells, grid.size() - occupied - free_cells, leaves);
  return 0;
}
