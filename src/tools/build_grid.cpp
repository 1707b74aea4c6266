// build_grid: run the sparse_nav perception core on a point file and write a map_server map.
//
//   build_grid FILE --out PREFIX [--up-axis -y] [--resolution R] [--scale METRES_PER_UNIT] [--json]
//              [--update FILE2] ...
//
// Writes PREFIX.pgm + PREFIX.yaml (map_server format) and PREFIX.png (a picture with the alpha
// polygons). Exit status: 0 ok, 2 bad input or no floor, 1 cannot write the outputs. The defaults
// are those of the core Config structs, which config/*.yaml repeat for the nodelets.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "sparse_nav/core/grid_pipeline.h"
#include "sparse_nav/core/point_file.h"

namespace
{
std::string usage()
{
  const sparse_nav::GridPipelineConfig d;
  char buf[4096];
  std::snprintf(
      buf, sizeof(buf),
      "usage: build_grid FILE --out PREFIX [options]\n"
      "\n"
      "Reads a point file (CSV/TXT/XYZ columns, PLY ascii/binary, PCD), finds the floor, and writes\n"
      "PREFIX.pgm + PREFIX.yaml (map_server format) and PREFIX.png. Defaults are the nodelets'.\n"
      "\n"
      "options:\n"
      "  --up-axis AXIS          nominal up axis of the file: x, -x, y, -y, z, -z (default -y: raw\n"
      "                          ORB-SLAM worlds are the first camera's optical frame, y down)\n"
      "  --resolution R          grid and octree cell size in metres (default %g)\n"
      "  --scale S               metres per SLAM unit (default 1). Monocular ORB-SLAM has no metric\n"
      "                          scale: without S every metric option below is in SLAM units\n"
      "  --max-tilt-deg D        largest floor tilt from the up axis (default %g)\n"
      "  --floor-distance M      RANSAC inlier distance of the floor plane (default %g)\n"
      "  --floor-planes N        near-horizontal planes tried for the floor (default %d)\n"
      "  --floor-clearance M     map z below which points are floor (default %g)\n"
      "  --ceiling-height M      map z above which points are ceiling (default %g)\n"
      "  --density METHOD        none, radius or ipcl (default radius)\n"
      "  --density-radius M      density filter radius (default %g)\n"
      "  --min-neighbors K       density filter neighbour count (default %d)\n"
      "  --leaf M                voxel leaf size, 0 disables the voxel grid (default %g)\n"
      "  --alpha M               alpha-shape radius in metres (default %g)\n"
      "  --auto-alpha            choose alpha from the nearest-neighbour spacing\n"
      "  --clear-hit-rays N      obstacle points whose cell N camera rays pass through at their height\n"
      "                          are dropped, 0: never\n"
      "                          (default %d)\n"
      "  --clear-segment-rays N  cells of singular alpha edges that N free rays cross stay free, 0: never\n"
      "                          (default %d)\n"
      "  --free-space-factor K   octree free space is ray-cast in voxels K times the resolution\n"
      "                          (1, 2, 4, ...; default %g)\n"
      "  --max-range M           octree rays longer than M are truncated (default: no limit)\n"
      "  --no-free-space-filter  keep obstacle points whose voxel the octree has proven free\n"
      "  --no-octree             skip the OctoMap octree\n"
      "  --save-octree           also write PREFIX.bt\n"
      "  --camera X,Y,Z          a camera position in the file's frame (repeatable); free-space rays\n"
      "                          start at the nearest one (default: the origin, ORB-SLAM's first camera)\n"
      "  --update FILE2          after FILE, process FILE2 (the changed cloud) as an incremental\n"
      "                          update of the same pipeline; the outputs show the updated grid\n"
      "  --repeat-update N       with --update, then go back to FILE and again to FILE2 N times,\n"
      "                          each an update; \"update\" gains their times (\"repeated_ms\")\n"
      "  --repeat-rebuild N      then rebuild FILE's grid from scratch N times in this process (reset, as\n"
      "                          a running node does on a map switch); \"repeated_rebuild_ms\" lists them\n"
      "  --json                  print {\"n_points\", \"stages_ms\", \"total_ms\", floor, grid} on stdout,\n"
      "                          with --update also \"update\": {\"stages_ms\", \"total_ms\", ..}\n",
      d.grid.resolution_m, d.ground.floor.max_tilt_deg, d.ground.floor.distance_threshold_m, d.ground.floor.max_planes,
      d.ground.floor_clearance_m, d.ground.ceiling_height_m, d.ground.density.radius_m, d.ground.density.min_neighbors,
      d.voxel.leaf_size_m, d.grid.alpha.alpha_m, d.ground.clear_hit_min_rays, d.grid.clear_segment_min_rays, d.ground.octree.free_space_resolution_m / d.ground.octree.resolution_m);
  return buf;
}

struct Args
{
  std::string file;
  std::string update;
  int repeat_update = 0;
  int repeat_rebuild = 0;
  std::string out;
  bool json = false;
  bool save_octree = false;
  std::string up_axis = "-y";
  sparse_nav::PointList cameras;
  sparse_nav::GridPipelineConfig config;
};

double number(const std::string& flag, const std::string& value)
{
  char* end = nullptr;
  const double v = std::strtod(value.c_str(), &end);
  if (value.empty() || end != value.c_str() + value.size() || !std::isfinite(v))
  {
    throw std::invalid_argument(flag + " needs a number, got '" + value + "'");
  }
  return v;
}

Args parseArgs(int argc, char** argv)
{
  Args a;
  double free_factor = a.config.ground.octree.free_space_resolution_m / a.config.ground.octree.resolution_m;
  for (int i = 1; i < argc; ++i)
  {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc)
      {
        throw std::invalid_argument(arg + " needs a value");
      }
      return argv[++i];
    };
    if (arg == "-h" || arg == "--help")
    {
      std::cout << usage();
      std::exit(0);
    }
    else if (arg == "--out")
      a.out = value();
    else if (arg == "--update")
      a.update = value();
    else if (arg == "--repeat-update")
      a.repeat_update = std::max(0, std::atoi(value().c_str()));
    else if (arg == "--repeat-rebuild")
      a.repeat_rebuild = std::max(0, std::atoi(value().c_str()));
    else if (arg == "--camera")
    {
      std::string v = value();
      for (char& c : v)
        c = c == ',' ? ' ' : c;
      std::istringstream in(v);
      double x, y, z;
      std::string rest;
      if (!(in >> x >> y >> z) || (in >> rest) || !std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
        throw std::invalid_argument("--camera needs X,Y,Z, got '" + std::string(argv[i]) + "'");
      a.cameras.emplace_back(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
    }
    else if (arg == "--floor-planes")
      a.config.ground.floor.max_planes = static_cast<int>(number(arg, value()));
    else if (arg == "--free-space-factor")
      free_factor = number(arg, value());
    else if (arg == "--max-range")
      a.config.ground.octree.max_range_m = number(arg, value());
    else if (arg == "--no-free-space-filter")
      a.config.ground.free_space_filter = false;
    else if (arg == "--json")
      a.json = true;
    else if (arg == "--up-axis")
      a.up_axis = value();
    else if (arg == "--resolution")
    {
      a.config.grid.resolution_m = number(arg, value());
      a.config.ground.octree.resolution_m = a.config.grid.resolution_m;
      a.config.ground.clear_cell_m = a.config.grid.resolution_m;
    }
    else if (arg == "--scale")
      a.config.metres_per_unit = number(arg, value());
    else if (arg == "--max-tilt-deg")
      a.config.ground.floor.max_tilt_deg = number(arg, value());
    else if (arg == "--floor-distance")
      a.config.ground.floor.distance_threshold_m = number(arg, value());
    else if (arg == "--floor-clearance")
      a.config.ground.floor_clearance_m = number(arg, value());
    else if (arg == "--ceiling-height")
      a.config.ground.ceiling_height_m = number(arg, value());
    else if (arg == "--density")
      a.config.ground.density.method = sparse_nav::densityMethodFromString(value());
    else if (arg == "--density-radius")
      a.config.ground.density.radius_m = number(arg, value());
    else if (arg == "--min-neighbors")
      a.config.ground.density.min_neighbors = static_cast<int>(number(arg, value()));
    else if (arg == "--leaf")
    {
      const double leaf = number(arg, value());
      a.config.voxel_enabled = leaf > 0.0;
      if (leaf > 0.0)
        a.config.voxel.leaf_size_m = leaf;
    }
    else if (arg == "--alpha")
      a.config.grid.alpha.alpha_m = number(arg, value());
    else if (arg == "--auto-alpha")
      a.config.grid.alpha.auto_alpha = true;
    else if (arg == "--clear-hit-rays")
      a.config.ground.clear_hit_min_rays = static_cast<int>(number(arg, value()));
    else if (arg == "--clear-height-tol")
      a.config.ground.clear_height_tolerance_m = number(arg, value());
    else if (arg == "--clear-segment-rays")
      a.config.grid.clear_segment_min_rays = static_cast<int>(number(arg, value()));
    else if (arg == "--no-octree")
      a.config.ground.octree_enabled = false;
    else if (arg == "--save-octree")
      a.save_octree = true;
    else if (!arg.empty() && arg[0] == '-' && arg.size() > 1)
      throw std::invalid_argument("unknown option " + arg);
    else if (a.file.empty())
      a.file = arg;
    else
      throw std::invalid_argument("more than one input file given ('" + a.file + "' and '" + arg + "')");
  }
  if (a.file.empty())
  {
    throw std::invalid_argument("no input FILE given");
  }
  if (a.out.empty())
  {
    throw std::invalid_argument("--out PREFIX is required");
  }
  a.config.ground.floor.up_axis = sparse_nav::axisFromString(a.up_axis);
  a.config.ground.octree.free_space_resolution_m = a.config.ground.octree.resolution_m * free_factor;
  a.config.validate();
  return a;
}

std::string jsonString(const std::string& s)
{
  std::string out = "\"";
  for (char c : s)
  {
    if (c == '"' || c == '\\')
    {
      out += '\\';
      out += c;
    }
    else if (static_cast<unsigned char>(c) < 0x20)
    {
      char buf[8];
      std::snprintf(buf, sizeof(buf), "\\u%04x", c);
      out += buf;
    }
    else
    {
      out += c;
    }
  }
  return out + "\"";
}

std::string baseName(const std::string& path)
{
  const auto slash = path.find_last_of('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

/// Grid rows run up in y; images run down: row 0 of the image is the grid's last row.
cv::Mat toPgm(const sparse_nav::OccupancyGrid& grid)
{
  cv::Mat img(grid.height, grid.width, CV_8UC1);
  for (int row = 0; row < grid.height; ++row)
  {
    std::uint8_t* out = img.ptr<std::uint8_t>(grid.height - 1 - row);
    for (int col = 0; col < grid.width; ++col)
    {
      const std::int8_t v = grid.at(col, row);
      out[col] = v == sparse_nav::OccupancyGrid::kOccupied ? 0 : v == sparse_nav::OccupancyGrid::kFree ? 254 : 205;
    }
  }
  return img;
}

bool writePgm(const std::string& path, const cv::Mat& img)
{
  std::ofstream out(path.c_str(), std::ios_base::binary);
  out << "P5\n" << img.cols << " " << img.rows << "\n255\n";
  for (int r = 0; r < img.rows; ++r)
  {
    out.write(reinterpret_cast<const char*>(img.ptr<std::uint8_t>(r)), img.cols);
  }
  return out.good();
}

cv::Mat picture(const sparse_nav::OccupancyGrid& grid, const sparse_nav::AlphaShapeResult& shape,
                const Eigen::Vector3d& camera)
{
  const int scale = std::max(1, std::min(8, 800 / std::max(1, std::max(grid.width, grid.height))));
  cv::Mat grey = toPgm(grid);
  cv::Mat colour;
  cv::cvtColor(grey, colour, cv::COLOR_GRAY2BGR);
  cv::resize(colour, colour, cv::Size(), scale, scale, cv::INTER_NEAREST);
  auto px = [&](const Eigen::Vector2d& p) {
    const double c = (p.x() - grid.origin_x_m) / grid.resolution_m;
    const double r = (p.y() - grid.origin_y_m) / grid.resolution_m;
    return cv::Point(static_cast<int>(c * scale), static_cast<int>((grid.height - r) * scale));
  };
  for (const auto& ring : shape.rings)
  {
    for (std::size_t i = 0; i < ring.size(); ++i)
    {
      cv::line(colour, px(ring[i]), px(ring[(i + 1) % ring.size()]), cv::Scalar(40, 40, 220), 1, cv::LINE_AA);
    }
  }
  for (const auto& s : shape.segments)
  {
    cv::line(colour, px(s.first), px(s.second), cv::Scalar(40, 160, 220), 1, cv::LINE_AA);
  }
  cv::circle(colour, px(camera.head<2>()), std::max(3, scale * 2), cv::Scalar(200, 120, 0), -1, cv::LINE_AA);
  return colour;
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
    std::cerr << "build_grid: " << e.what() << "\n\n" << usage();
    return 2;
  }

  const auto t_read = std::chrono::steady_clock::now();
  const sparse_nav::PointFileResult file = sparse_nav::readPointFile(args.file);
  const double read_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_read).count();
  if (!file.ok)
  {
    std::cerr << "build_grid: " << file.error << "\n";
    return 2;
  }
  if (file.n_non_finite > 0)
  {
    std::cerr << "build_grid: warning: " << file.n_non_finite << " of " << file.n_rows
              << " rows have a NaN or infinite coordinate and were dropped\n";
  }

  sparse_nav::GridPipeline pipeline(args.config);
  sparse_nav::GridPipelineResult result = pipeline.process(file.points, args.cameras);
  result.stages_ms["read"] = read_ms;

  std::ostringstream json;
  json.setf(std::ios::fixed);
  json.precision(3);
  auto writeJsonHead = [&]() {
    json << "{\"file\": " << jsonString(args.file) << ", \"n_points\": " << file.points.size()
         << ", \"n_non_finite\": " << file.n_non_finite << ", \"stages_ms\": {";
    bool first = true;
    double total = 0.0;
    for (const auto& kv : result.stages_ms)
    {
      json << (first ? "" : ", ") << jsonString(kv.first) << ": " << kv.second;
      total += kv.second;
      first = false;
    }
    json << "}, \"total_ms\": " << total;
    const auto& f = result.floor;
    json << ", \"floor\": {\"found\": " << (f.found ? "true" : "false");
    if (f.found)
    {
      json << ", \"tilt_deg\": " << f.plane.tilt_deg << ", \"normal\": [" << f.plane.normal.x() << ", "
           << f.plane.normal.y() << ", " << f.plane.normal.z() << "], \"d\": " << f.plane.d
           << ", \"inliers\": " << f.plane.n_inliers;
    }
    else
    {
      json << ", \"reason\": " << jsonString(f.reason);
    }
    json << "}";
  };

  // A cloud whose points all fall outside the obstacle band and cast no free ray gives no grid.
  const bool empty_grid = result.ok && (pipeline.grid().width == 0 || pipeline.grid().height == 0);
  if (!result.ok || empty_grid)
  {
    std::string message = empty_grid ? "no grid to write: " + result.status : result.status;
    if (empty_grid && args.config.metres_per_unit == 1.0)
    {
      message += " (without --scale the floor and ceiling bands are in SLAM units, and a small monocular map "
                 "fits inside the floor band)";
    }
    if (!result.floor.found && !result.floor.reason.empty())
    {
      char buf[400];
      const double tilt = result.floor.best_plane_tilt_deg;
      if (std::isfinite(tilt))
      {
        std::snprintf(buf, sizeof(buf),
                      "no floor plane within %.0f deg of the up axis %s; the best-supported floor-like plane is "
                      "tilted %.1f deg: pass --max-tilt-deg or --up-axis",
                      args.config.ground.floor.max_tilt_deg, args.up_axis.c_str(), tilt);
      }
      else
      {
        std::snprintf(buf, sizeof(buf),
                      "no floor plane within %.0f deg of the up axis %s (%s): check --up-axis",
                      args.config.ground.floor.max_tilt_deg, args.up_axis.c_str(), result.floor.reason.c_str());
      }
      message = buf;
    }
    std::cerr << "build_grid: " << args.file << ": " << message << "\n";
    if (args.json)
    {
      writeJsonHead();
      json << ", \"error\": " << jsonString(message) << "}";
      std::cout << json.str() << std::endl;
    }
    return 2;
  }

  // The changed cloud as an incremental update of the same pipeline.
  sparse_nav::GridPipelineResult update;
  std::vector<double> repeated_ms;
  if (!args.update.empty())
  {
    const auto t_read2 = std::chrono::steady_clock::now();
    const sparse_nav::PointFileResult file2 = sparse_nav::readPointFile(args.update);
    const double read2_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_read2).count();
    if (!file2.ok)
    {
      std::cerr << "build_grid: --update: " << file2.error << "\n";
      return 2;
    }
    update = pipeline.process(file2.points, args.cameras);
    update.stages_ms["read"] = read2_ms;
    if (!update.ok)
    {
      std::cerr << "build_grid: --update " << args.update << ": " << update.status << "\n";
      return 2;
    }
    // Updates after the first, as a map refreshed again and again sees them: back to FILE, then
    // FILE2 again, each differing from the one before by the same points.
    for (int k = 0; k < 2 * args.repeat_update; ++k)
    {
      const sparse_nav::GridPipelineResult again = pipeline.process(k % 2 == 0 ? file.points : file2.points, args.cameras);
      if (!again.ok)
      {
        std::cerr << "build_grid: --repeat-update: " << again.status << "\n";
        return 2;
      }
      repeated_ms.push_back(again.total_ms);
    }
  }
  // Rebuilds in a process whose memory is already mapped: the first build above also paid for
  // first touching every page it used. A second pipeline keeps the outputs those of the first.
  std::vector<double> repeated_rebuild_ms;
  if (args.repeat_rebuild > 0)
  {
    sparse_nav::GridPipeline again(args.config);
    for (int k = 0; k < args.repeat_rebuild; ++k)
    {
      again.reset();
      const sparse_nav::GridPipelineResult rebuilt = again.process(file.points, args.cameras);
      if (!rebuilt.ok)
      {
        std::cerr << "build_grid: --repeat-rebuild: " << rebuilt.status << "\n";
        return 2;
      }
      repeated_rebuild_ms.push_back(rebuilt.total_ms);
    }
  }
  std::map<std::string, double>& last_stages = args.update.empty() ? result.stages_ms : update.stages_ms;

  const auto t_write = std::chrono::steady_clock::now();
  const sparse_nav::OccupancyGrid& grid = pipeline.grid();
  const std::string pgm = args.out + ".pgm", yaml = args.out + ".yaml", png = args.out + ".png";
  bool written = writePgm(pgm, toPgm(grid));
  {
    std::ofstream y(yaml.c_str());
    char origin[128];
    std::snprintf(origin, sizeof(origin), "[%.6f, %.6f, 0.0]", grid.origin_x_m, grid.origin_y_m);
    y << "image: " << baseName(pgm) << "\nresolution: " << grid.resolution_m << "\norigin: " << origin
      << "\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";
    written = written && y.good();
  }
  try
  {
    const Eigen::Vector3d first = args.cameras.empty() ? Eigen::Vector3d::Zero()
                                                       : Eigen::Vector3d(args.cameras.front().cast<double>() *
                                                                         args.config.metres_per_unit);
    const Eigen::Vector3d camera = result.slam_to_map * first;
    written = written && cv::imwrite(png, picture(grid, pipeline.builder().lastShape(), camera));
  }
  catch (const cv::Exception& e)
  {
    std::cerr << "build_grid: " << png << ": " << e.what() << "\n";
    written = false;
  }
  if (args.save_octree && pipeline.octree())
  {
    const sparse_nav::IoStatus st = pipeline.octree()->save(args.out + ".bt");
    if (!st.ok)
    {
      std::cerr << "build_grid: " << st.message << "\n";
      written = false;
    }
  }
  last_stages["write"] = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_write).count();
  if (!written)
  {
    std::cerr << "build_grid: could not write the outputs " << args.out << ".{pgm,yaml,png}\n";
    return 1;
  }
  if (args.json)
  {
    writeJsonHead();
    json << ", \"grid\": {\"width\": " << grid.width << ", \"height\": " << grid.height
         << ", \"resolution\": " << grid.resolution_m << ", \"origin\": [" << grid.origin_x_m << ", " << grid.origin_y_m
         << "], \"occupied\": " << grid.count(sparse_nav::OccupancyGrid::kOccupied)
         << ", \"free\": " << grid.count(sparse_nav::OccupancyGrid::kFree)
         << ", \"unknown\": " << grid.count(sparse_nav::OccupancyGrid::kUnknown) << ", \"alpha_m\": " << result.grid.alpha_m
         << ", \"polygons\": " << pipeline.builder().lastShape().rings.size() << "}";
    json << ", \"octree\": {\"new_voxels\": " << result.octree.n_new_voxels << ", \"rays\": " << result.octree.n_rays
         << ", \"free_voxels\": " << result.octree.n_free_voxels << ", \"leaves\": "
         << (pipeline.octree() ? pipeline.octree()->numLeafNodes() : 0) << "}";
    if (!args.update.empty())
    {
      json << ", \"update\": {\"file\": " << jsonString(args.update) << ", \"stages_ms\": {";
      bool first = true;
      double total = 0.0;
      for (const auto& kv : update.stages_ms)
      {
        json << (first ? "" : ", ") << jsonString(kv.first) << ": " << kv.second;
        total += kv.second;
        first = false;
      }
      json << "}, \"total_ms\": " << total << ", \"full_rebuild\": " << (update.grid.full_rebuild ? "true" : "false")
           << ", \"recomputed_tiles\": " << update.grid.recomputed_tiles.size()
           << ", \"changed_tiles\": " << update.grid.changed_tiles.size()
           << ", \"tiles\": " << (grid.width / args.config.grid.tile_size_cells) * (grid.height / args.config.grid.tile_size_cells)
           << ", \"changed_points\": " << update.n_changed_points << ", \"density_counted\": " << update.density.n_counted
           << ", \"octree_new_voxels\": " << update.octree.n_new_voxels << ", \"octree_rays\": " << update.octree.n_rays
           << ", \"obstacles\": " << update.n_obstacles << ", \"freed\": " << update.n_freed << ", \"repeated_ms\": [";
      for (std::size_t k = 0; k < repeated_ms.size(); ++k)
      {
        json << (k ? ", " : "") << repeated_ms[k];
      }
      json << "]}";
    }
    json << ", \"repeated_rebuild_ms\": [";
    for (std::size_t k = 0; k < repeated_rebuild_ms.size(); ++k)
    {
      json << (k ? ", " : "") << repeated_rebuild_ms[k];
    }
    json << "]";
    json << ", \"filtered\": {\"guard_out\": " << result.guard.n_out << ", \"density_out\": " << result.density.n_out
         << ", \"voxel_out\": " << result.voxel.n_out << ", \"obstacles\": " << result.n_obstacles
         << ", \"freed\": " << result.n_freed
         << ", \"floor_band\": " << result.n_floor_band << ", \"ceiling_band\": " << result.n_ceiling_band << "}";
    json << ", \"outputs\": [" << jsonString(pgm) << ", " << jsonString(yaml) << ", " << jsonString(png) << "]}";
    std::cout << json.str() << std::endl;
  }
  else
  {
    std::cout << "build_grid: " << args.file << ": " << result.status << "\n";
    if (!args.update.empty())
    {
      std::cout << "build_grid: --update " << args.update << ": " << update.status << "\n";
    }
    std::cout << "  wrote " << pgm << ", " << yaml << ", " << png << "\n";
  }
  return 0;
}
