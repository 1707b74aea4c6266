#include "sparse_nav/core/scan_file.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <sstream>

#include <zlib.h>

namespace sparse_nav
{
namespace
{
bool toNumber(const std::string& s, double& v)
{
  if (s.empty())
    return false;
  char* end = nullptr;
  errno = 0;
  v = std::strtod(s.c_str(), &end);
  return end == s.c_str() + s.size() && errno != ERANGE;
}

std::vector<std::string> split(const std::string& line, char sep)
{
  std::vector<std::string> out;
  if (sep == ' ')
  {
    std::istringstream in(line);
    std::string tok;
    while (in >> tok)
      out.push_back(tok);
    return out;
  }
  std::string cur;
  for (char c : line)
  {
    if (c == sep)
    {
      out.push_back(cur);
      cur.clear();
    }
    else if (c != ' ' && c != '\t' && c != '\r')
    {
      cur.push_back(c);
    }
  }
  out.push_back(cur);
  return out;
}

/// Reads tokens[first, first + n) as numbers; false at the first one that is not.
bool numbers(const std::vector<std::string>& tokens, std::size_t first, std::size_t n, std::vector<double>& out)
{
  if (first + n > tokens.size())
    return false;
  out.resize(n);
  for (std::size_t i = 0; i < n; ++i)
    if (!toNumber(tokens[first + i], out[i]))
      return false;
  return true;
}

bool countOf(const std::string& token, std::size_t max, std::size_t& n)
{
  double v = 0.0;
  if (!toNumber(token, v) || !(v >= 0.0) || v > static_cast<double>(max) || v != std::floor(v))
    return false;
  n = static_cast<std::size_t>(v);
  return true;
}

constexpr std::size_t kMaxBeams = 100000;

std::string parseFlaser(const std::vector<std::string>& t, ScanRecord& rec)
{
  std::size_t n = 0;
  if (t.size() < 2 || !countOf(t[1], kMaxBeams, n) || n < 2)
    return "FLASER needs a beam count >= 2";
  std::vector<double> v;
  if (!numbers(t, 2, n, v))
    return "FLASER has fewer than " + std::to_string(n) + " numeric ranges";
  std::vector<double> pose;
  if (!numbers(t, 2 + n, 3, pose))
    return "FLASER has no pose after its ranges";
  // CARMEN's front laser spans 180 degrees; an odd count has beams at both ends.
  const double inc = n % 2 ? M_PI / static_cast<double>(n - 1) : M_PI / static_cast<double>(n);
  rec.scan.angle_min_rad = -M_PI / 2.0;
  rec.scan.angle_increment_rad = inc;
  rec.scan.angle_max_rad = -M_PI / 2.0 + static_cast<double>(n - 1) * inc;
  rec.scan.ranges.assign(v.begin(), v.end());
  rec.has_pose = std::isfinite(pose[0]) && std::isfinite(pose[1]) && std::isfinite(pose[2]);
  rec.pose = { pose[0], pose[1], pose[2] };
  return std::string();
}

std::string parseRobotLaser(const std::vector<std::string>& t, ScanRecord& rec)
{
  std::vector<double> head;
  std::size_t n = 0;
  if (!numbers(t, 1, 7, head) || t.size() < 9 || !countOf(t[8], kMaxBeams, n) || n < 2)
    return "ROBOTLASER1 header (type, start angle, fov, resolution, max range, accuracy, remission mode, count) unreadable";
  std::vector<double> v;
  if (!numbers(t, 9, n, v))
    return "ROBOTLASER1 has fewer than " + std::to_string(n) + " numeric ranges";
  std::size_t n_rem = 0;
  if (t.size() <= 9 + n || !countOf(t[9 + n], kMaxBeams, n_rem))
    return "ROBOTLASER1 remission count unreadable";
  std::vector<double> pose;
  if (!numbers(t, 10 + n + n_rem, 3, pose))
    return "ROBOTLASER1 has no laser pose";
  rec.scan.angle_min_rad = head[1];
  rec.scan.angle_increment_rad = head[3];
  rec.scan.angle_max_rad = head[1] + static_cast<double>(n - 1) * head[3];
  if (std::isfinite(head[4]) && head[4] > 0.0)
    rec.scan.range_max_m = head[4];
  rec.scan.ranges.assign(v.begin(), v.end());
  rec.has_pose = std::isfinite(pose[0]) && std::isfinite(pose[1]) && std::isfinite(pose[2]);
  rec.pose = { pose[0], pose[1], pose[2] };
  return std::string();
}

std::string parseCsvRow(const std::vector<std::string>& t, ScanRecord& rec)
{
  std::vector<double> head;
  if (!numbers(t, 0, 7, head))
    return "a CSV scan row starts with 7 numbers (angle_min, angle_max, increment, range_max, x, y, yaw)";
  if (t.size() - 7 > kMaxBeams)
    return "too many ranges";
  std::vector<double> v;
  if (!numbers(t, 7, t.size() - 7, v))
    return "a range is not a number";
  rec.scan.angle_min_rad = head[0];
  rec.scan.angle_max_rad = head[1];
  rec.scan.angle_increment_rad = head[2];
  rec.scan.range_max_m = head[3] > 0.0 ? head[3] : rec.scan.range_max_m;
  rec.scan.ranges.assign(v.begin(), v.end());
  rec.has_pose = std::isfinite(head[4]) && std::isfinite(head[5]) && std::isfinite(head[6]);
  rec.pose = { head[4], head[5], head[6] };
  return std::string();
}
}  // namespace

ScanFileResult parseScanText(const std::string& text, const std::string& format)
{
  ScanFileResult res;
  res.format = format;
  if (format != "carmen" && format != "csv")
  {
    res.error = "unknown format '" + format + "' (carmen or csv)";
    return res;
  }
  if (text.find('\0') != std::string::npos)
  {
    res.error = "not a text file (contains NUL bytes)";
    return res;
  }
  std::istringstream in(text);
  std::string line;
  std::size_t line_no = 0;
  bool first_row = true;
  while (std::getline(in, line))
  {
    ++line_no;
    if (!line.empty() && line.back() == '\r')
      line.pop_back();
    if (line.empty() || line[0] == '#')
      continue;
    ScanRecord rec;
    rec.line = line_no;
    std::string problem;
    if (format == "carmen")
    {
      const std::vector<std::string> t = split(line, ' ');
      if (t.empty())
        continue;
      if (t[0] == "FLASER")
        problem = parseFlaser(t, rec);
      else if (t[0] == "ROBOTLASER1")
        problem = parseRobotLaser(t, rec);
      else
        continue;
    }
    else
    {
      if (first_row && std::isalpha(static_cast<unsigned char>(line[0])))
      {
        first_row = false;
        continue;  // header
      }
      first_row = false;
      problem = parseCsvRow(split(line, ','), rec);
    }
    if (!problem.empty())
    {
      if (res.n_bad_lines++ == 0)
        res.first_bad_line = "line " + std::to_string(line_no) + ": " + problem;
      continue;
    }
    res.scans.push_back(std::move(rec));
  }
  if (res.scans.empty())
  {
    res.error = format == "carmen" ? "no readable FLASER or ROBOTLASER1 line" : "no readable CSV scan row";
    if (res.n_bad_lines > 0)
      res.error += " (" + res.first_bad_line + ")";
    return res;
  }
  res.ok = true;
  return res;
}

ScanFileResult readScanFile(const std::string& path, const std::string& format)
{
  std::string fmt = format;
  if (fmt == "auto")
  {
    const auto ends = [&path](const std::string& s) {
      return path.size() >= s.size() && path.compare(path.size() - s.size(), s.size(), s) == 0;
    };
    fmt = ends(".csv") || ends(".csv.gz") ? "csv" : "carmen";
  }
  ScanFileResult res;
  res.format = fmt;
  // gzread passes plain files through unchanged.
  gzFile gz = gzopen(path.c_str(), "rb");
  if (!gz)
  {
    res.error = "cannot open '" + path + "': " + std::strerror(errno);
    return res;
  }
  std::string text;
  char buf[1 << 16];
  int got = 0;
  while ((got = gzread(gz, buf, sizeof(buf))) > 0)
    text.append(buf, static_cast<std::size_t>(got));
  int err = 0;
  const char* msg = gzerror(gz, &err);
  const bool failed = got < 0 || (err != Z_OK && err != Z_STREAM_END);
  const std::string why = failed && msg ? msg : "";
  gzclose(gz);
  if (failed)
  {
    res.error = "cannot read '" + path + "': " + why;
    return res;
  }
  return parseScanText(text, fmt);
}
}  // namespace sparse_nav
