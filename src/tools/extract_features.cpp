// extract_features: walls, doors, corners and corridors (seed 002) from the scans of a file.
//
//   extract_features FILE [--format auto|carmen|csv] [--summary] [--json] [--match] [--world] ...
//
// Exit status: 0 ok, 2 bad arguments or an unreadable file.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "sparse_nav/core/line_features.h"
#include "sparse_nav/core/scan_file.h"

namespace
{
const char* const kUsage =
    "usage: extract_features FILE [options]\n"
    "\n"
    "Extracts walls, doors, corners and corridors from every scan of a CARMEN log (FLASER and\n"
    "ROBOTLASER1 lines; plain or .gz) or a CSV scan file (one scan per row: angle_min_rad,\n"
    "angle_max_rad, angle_increment_rad, range_max_m, x_m, y_m, yaw_rad, ranges...).\n"
    "\n"
    "options:\n"
    "  --format F          auto (default: .csv is CSV, anything else CARMEN), carmen or csv\n"
    "  --json              print JSON: per scan walls [x1, y1, x2, y2], doors [x1, y1, x2, y2],\n"
    "                      corners {x, y, type}, corridors; then counts and timings\n"
    "  --summary           counts and timings only (text, or JSON with --json)\n"
    "  --match             align consecutive scans (Procrustes, nearest neighbours iterated)\n"
    "                      and compare with the file's poses: median translation/rotation error\n"
    "  --world             features in the file's world frame (each scan's pose) instead of the\n"
    "                      sensor frame; scans without a pose stay in the sensor frame\n"
    "  --pair-max M        --match pairs nearest neighbours up to M metres apart (default 1)\n"
    "  --repeat N          extract every scan N times (steadier timings; default 1)\n"
    "  --max-range M       returns beyond M metres are ruptures (default 30)\n"
    "  --door-min M        narrowest door (default 0.8)\n"
    "  --door-max M        widest door (default 1.2)\n"
    "  --lambda-deg D      breakpoint incidence angle lambda (default 10)\n"
    "  --sigma M           range noise sigma of the breakpoint bound (default 0.01)\n"
    "  --split M           iterative end-point fit threshold (default 0.05)\n"
    "  --min-wall M        shortest wall (default 0.25)\n";

struct Args
{
  std::string file;
  std::string format = "auto";
  bool json = false;
  bool summary = false;
  bool match = false;
  bool world = false;
  int repeat = 1;
  sparse_nav::LineFeatureConfig config;
  sparse_nav::ProcrustesConfig procrustes;
};

double number(const std::string& flag, const std::string& value)
{
  char* end = nullptr;
  const double v = std::strtod(value.c_str(), &end);
  if (value.empty() || end != value.c_str() + value.size() || !std::isfinite(v))
    throw std::invalid_argument(flag + " needs a number, got '" + value + "'");
  return v;
}

Args parseArgs(int argc, char** argv)
{
  Args a;
  for (int i = 1; i < argc; ++i)
  {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc)
        throw std::invalid_argument(arg + " needs a value");
      return argv[++i];
    };
    if (arg == "-h" || arg == "--help")
    {
      std::cout << kUsage;
      std::exit(0);
    }
    else if (arg == "--format")
      a.format = value();
    else if (arg == "--json")
      a.json = true;
    else if (arg == "--summary")
      a.summary = true;
    else if (arg == "--match")
      a.match = true;
    else if (arg == "--world")
      a.world = true;
    else if (arg == "--repeat")
    {
      const double r = number(arg, value());
      if (r < 1 || r > 10000 || r != std::floor(r))
        throw std::invalid_argument("--repeat needs an integer in [1, 10000]");
      a.repeat = static_cast<int>(r);
    }
    else if (arg == "--pair-max")
      a.procrustes.max_correspondence_m = number(arg, value());
    else if (arg == "--max-range")
      a.config.max_range_m = number(arg, value());
    else if (arg == "--door-min")
      a.config.door_min_width_m = number(arg, value());
    else if (arg == "--door-max")
      a.config.door_max_width_m = number(arg, value());
    else if (arg == "--lambda-deg")
      a.config.breakpoint_lambda_deg = number(arg, value());
    else if (arg == "--sigma")
      a.config.breakpoint_sigma_m = number(arg, value());
    else if (arg == "--split")
      a.config.split_distance_m = number(arg, value());
    else if (arg == "--min-wall")
      a.config.min_wall_length_m = number(arg, value());
    else if (!arg.empty() && arg[0] == '-')
      throw std::invalid_argument("unknown option " + arg);
    else if (a.file.empty())
      a.file = arg;
    else
      throw std::invalid_argument("more than one FILE given");
  }
  if (a.file.empty())
    throw std::invalid_argument("no FILE given");
  if (a.format != "auto" && a.format != "carmen" && a.format != "csv")
    throw std::invalid_argument("--format must be auto, carmen or csv (bag input is not supported)");
  a.config.validate();
  a.procrustes.validate();
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
      out += c;
  }
  return out + "\"";
}

std::string num(double v, int digits = 4)
{
  if (!std::isfinite(v))
    return "null";
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", digits, v);
  return buf;
}

double median(std::vector<double> v)
{
  if (v.empty())
    return std::nan("");
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + mid, v.end());
  return v[mid];
}

double percentile(std::vector<double> v, double q)
{
  if (v.empty())
    return std::nan("");
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5))];
}

Eigen::Isometry2d poseToIso(const sparse_nav::Pose2D& p)
{
  Eigen::Isometry2d t = Eigen::Isometry2d::Identity();
  t.translate(Eigen::Vector2d(p.x_m, p.y_m));
  t.rotate(p.yaw_rad);
  return t;
}

void printScanJson(std::ostream& out, std::size_t index, const sparse_nav::ScanRecord& rec,
                   const sparse_nav::ScanFeatures& f)
{
  out << "{\"index\": " << index << ", \"line\": " << rec.line << ", \"ok\": " << (f.ok ? "true" : "false");
  if (!f.ok)
    out << ", \"reason\": " << jsonString(f.reason);
  out << ", \"walls\": [";
  for (std::size_t i = 0; i < f.walls.size(); ++i)
  {
    const auto& w = f.walls[i];
    out << (i ? ", " : "") << "[" << num(w.start.x()) << ", " << num(w.start.y()) << ", " << num(w.end.x()) << ", "
        << num(w.end.y()) << "]";
  }
  out << "], \"doors\": [";
  for (std::size_t i = 0; i < f.doors.size(); ++i)
  {
    const auto& d = f.doors[i];
    out << (i ? ", " : "") << "[" << num(d.start.x()) << ", " << num(d.start.y()) << ", " << num(d.end.x()) << ", "
        << num(d.end.y()) << "]";
  }
  out << "], \"corners\": [";
  for (std::size_t i = 0; i < f.corners.size(); ++i)
  {
    const auto& c = f.corners[i];
    out << (i ? ", " : "") << "{\"x\": " << num(c.point.x()) << ", \"y\": " << num(c.point.y())
        << ", \"type\": \"" << sparse_nav::cornerTypeName(c.type) << "\", \"angle_deg\": " << num(c.angle_deg, 1)
        << "}";
  }
  out << "], \"corridors\": [";
  for (std::size_t i = 0; i < f.corridors.size(); ++i)
  {
    const auto& c = f.corridors[i];
    auto list = [&out](const std::vector<std::size_t>& v) {
      out << "[";
      for (std::size_t k = 0; k < v.size(); ++k)
        out << (k ? ", " : "") << v[k];
      out << "]";
    };
    out << (i ? ", " : "") << "{\"width_m\": " << num(c.width_m, 3) << ", \"length_m\": " << num(c.length_m, 3)
        << ", \"side_a\": ";
    list(c.side_a);
    out << ", \"side_b\": ";
    list(c.side_b);
    out << "}";
  }
  out << "]}";
}

struct MatchStats
{
  std::size_t pairs = 0, failed = 0;
  std::vector<double> trans_err_m, rot_err_deg, motion_m, motion_deg;
  double total_ms = 0.0;
};

MatchStats matchConsecutive(const std::vector<sparse_nav::ScanRecord>& scans, const sparse_nav::LineFeatureConfig& cfg,
                            const sparse_nav::ProcrustesConfig& pcfg)
{
  MatchStats st;
  std::vector<sparse_nav::PointList2D> points(scans.size());
  for (std::size_t i = 0; i < scans.size(); ++i)
    points[i] = sparse_nav::scanPoints(scans[i].scan, cfg.min_range_m, cfg.max_range_m);
  const auto t0 = std::chrono::steady_clock::now();
  Eigen::Isometry2d last = Eigen::Isometry2d::Identity();
  bool have_last = false;
  auto better = [](const sparse_nav::ProcrustesResult& a, const sparse_nav::ProcrustesResult& b) {
    return a.inlier_fraction > b.inlier_fraction;
  };
  for (std::size_t i = 1; i < scans.size(); ++i)
  {
    if (!scans[i - 1].has_pose || !scans[i].has_pose)
    {
      have_last = false;
      continue;
    }
    ++st.pairs;
    // Maps scan i's points into scan i-1's frame; the truth is pose(i-1)^-1 * pose(i). Starts: at
    // rest and at the previous estimated motion (constant velocity), each turned by 0 and +-15 deg
    // (nearest neighbours only pull a few degrees); the one that overlaps most wins.
    sparse_nav::ProcrustesResult r;
    for (int k = 0; k < (have_last ? 2 : 1); ++k)
      for (double turn_deg : { 0.0, -15.0, 15.0 })
      {
        Eigen::Isometry2d start = k == 0 ? Eigen::Isometry2d::Identity() : last;
        start.rotate(turn_deg * M_PI / 180.0);
        const auto candidate = sparse_nav::alignScans(points[i], points[i - 1], pcfg, start);
        if (candidate.ok && (!r.ok || better(candidate, r)))
          r = candidate;
      }
    have_last = r.ok;
    if (r.ok)
      last = r.transform;
    const Eigen::Isometry2d truth = poseToIso(scans[i - 1].pose).inverse() * poseToIso(scans[i].pose);
    st.motion_m.push_back(truth.translation().norm());
    st.motion_deg.push_back(std::abs(Eigen::Rotation2Dd(truth.linear()).angle()) * 180.0 / M_PI);
    if (!r.ok)
    {
      ++st.failed;
      continue;
    }
    const Eigen::Isometry2d err = truth.inverse() * r.transform;
    st.trans_err_m.push_back((r.transform.translation() - truth.translation()).norm());
    st.rot_err_deg.push_back(std::abs(Eigen::Rotation2Dd(err.linear()).angle()) * 180.0 / M_PI);
  }
  st.total_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return st;
}

int run(const Args& args)
{
  const auto p0 = std::chrono::steady_clock::now();
  const sparse_nav::ScanFileResult file = sparse_nav::readScanFile(args.file, args.format);
  const double parse_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - p0).count();
  if (!file.ok)
  {
    std::cerr << "extract_features: " << args.file << ": " << file.error << "\n";
    return 2;
  }
  const sparse_nav::LineFeatureExtractor extractor(args.config);
  std::vector<sparse_nav::ScanFeatures> features(file.scans.size());
  std::vector<double> per_scan_us(file.scans.size(), 0.0);
  const auto t0 = std::chrono::steady_clock::now();
  for (int rep = 0; rep < args.repeat; ++rep)
    for (std::size_t i = 0; i < file.scans.size(); ++i)
    {
      const auto s0 = std::chrono::steady_clock::now();
      features[i] = extractor.extract(file.scans[i].scan);
      per_scan_us[i] += std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - s0).count();
    }
  const double total_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() / args.repeat;
  for (auto& us : per_scan_us)
    us /= args.repeat;
  if (args.world)
    for (std::size_t i = 0; i < features.size(); ++i)
      if (file.scans[i].has_pose)
        sparse_nav::transformFeatures(features[i], poseToIso(file.scans[i].pose));

  std::size_t n_ok = 0, walls = 0, doors = 0, corridors = 0, inner = 0, outer = 0, potential = 0, beams = 0;
  for (std::size_t i = 0; i < features.size(); ++i)
  {
    const auto& f = features[i];
    n_ok += f.ok;
    walls += f.walls.size();
    doors += f.doors.size();
    corridors += f.corridors.size();
    beams = std::max(beams, file.scans[i].scan.ranges.size());
    for (const auto& c : f.corners)
    {
      inner += c.type == sparse_nav::CornerType::kInner;
      outer += c.type == sparse_nav::CornerType::kOuter;
      potential += c.type == sparse_nav::CornerType::kPotential;
    }
  }
  const std::size_t n = features.size();
  const double scans_per_s = total_ms > 0.0 ? 1000.0 * static_cast<double>(n) / total_ms : std::nan("");
  MatchStats match;
  if (args.match)
    match = matchConsecutive(file.scans, args.config, args.procrustes);

  std::ostream& out = std::cout;
  if (args.json)
  {
    out << "{\"file\": " << jsonString(args.file) << ", \"format\": \"" << file.format << "\", \"n_scans\": " << n
        << ", \"n_ok\": " << n_ok << ", \"n_bad_lines\": " << file.n_bad_lines << ", \"max_beams\": " << beams;
    if (!args.summary)
    {
      out << ",\n \"scans\": [\n  ";
      for (std::size_t i = 0; i < n; ++i)
      {
        if (i)
          out << ",\n  ";
        printScanJson(out, i, file.scans[i], features[i]);
      }
      out << "\n ]";
    }
    out << ",\n \"counts\": {\"walls\": " << walls << ", \"doors\": " << doors << ", \"corners_inner\": " << inner
        << ", \"corners_outer\": " << outer << ", \"corners_potential\": " << potential
        << ", \"corridors\": " << corridors << "}";
    out << ",\n \"parse_ms\": " << num(parse_ms, 3) << ", \"total_ms\": " << num(total_ms, 3)
        << ", \"scans_per_s\": " << num(scans_per_s, 1) << ", \"median_us_per_scan\": " << num(median(per_scan_us), 2)
        << ", \"repeat\": " << args.repeat;
    if (args.match)
      out << ",\n \"match\": {\"pairs\": " << match.pairs << ", \"failed\": " << match.failed
          << ", \"median_translation_error_m\": " << num(median(match.trans_err_m))
          << ", \"median_rotation_error_deg\": " << num(median(match.rot_err_deg), 3)
          << ", \"p90_translation_error_m\": " << num(percentile(match.trans_err_m, 0.9))
          << ", \"p90_rotation_error_deg\": " << num(percentile(match.rot_err_deg, 0.9), 3)
          << ", \"median_motion_m\": " << num(median(match.motion_m))
          << ", \"median_motion_deg\": " << num(median(match.motion_deg), 3)
          << ", \"total_ms\": " << num(match.total_ms, 3) << "}";
    out << "\n}\n";
    return 0;
  }
  if (!args.summary)
  {
    for (std::size_t i = 0; i < n; ++i)
    {
      const auto& f = features[i];
      out << "scan " << i << " (line " << file.scans[i].line << "): ";
      if (!f.ok)
      {
        out << "refused: " << f.reason << "\n";
        continue;
      }
      out << f.walls.size() << " walls, " << f.doors.size() << " doors, " << f.corners.size() << " corners, "
          << f.corridors.size() << " corridors\n";
    }
  }
  out << args.file << " (" << file.format << "): " << n << " scans (" << n - n_ok << " refused, " << file.n_bad_lines
      << " unreadable lines), up to " << beams << " beams\n";
  out << "  walls " << walls << ", doors " << doors << ", corners " << inner << " inner / " << outer << " outer / "
      << potential << " potential, corridors " << corridors << "\n";
  out << "  extraction " << num(total_ms, 1) << " ms (" << num(scans_per_s, 0) << " scans/s, median "
      << num(median(per_scan_us), 1) << " us/scan), parsing " << num(parse_ms, 1) << " ms\n";
  if (args.match)
    out << "  match: " << match.pairs << " pairs, " << match.failed << " failed; median error "
        << num(median(match.trans_err_m), 3) << " m, " << num(median(match.rot_err_deg), 2)
        << " deg (median motion " << num(median(match.motion_m), 3) << " m, " << num(median(match.motion_deg), 2)
        << " deg)\n";
  return 0;
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
    std::cerr << "extract_features: " << e.what() << "\n\n" << kUsage;
    return 2;
  }
  try
  {
    return run(args);
  }
  catch (const std::exception& e)
  {
    std::cerr << "extract_features: " << e.what() << "\n";
    return 2;
  }
}
