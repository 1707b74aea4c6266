#include "sparse_nav/core/point_file.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <fstream>
#include <iterator>
#include <sstream>
#include <stdexcept>
#include <vector>

#include <pcl/PCLPointCloud2.h>
#include <pcl/conversions.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

namespace sparse_nav
{
namespace
{
struct FileError : std::runtime_error
{
  using std::runtime_error::runtime_error;
};

bool parseNumber(const std::string& token, double& value)
{
  if (token.empty())
  {
    return false;
  }
  char* end = nullptr;
  value = std::strtod(token.c_str(), &end);
  return end == token.c_str() + token.size();
}

std::string trim(const std::string& s)
{
  const auto b = s.find_first_not_of(" \t\r\v\f");
  if (b == std::string::npos)
  {
    return "";
  }
  const auto e = s.find_last_not_of(" \t\r\v\f");
  return s.substr(b, e - b + 1);
}

/// Fields of a text line; comma/semicolon lines keep inner empty fields, trailing ones are dropped.
std::vector<std::string> splitFields(const std::string& line)
{
  std::vector<std::string> fields;
  if (line.find_first_of(",;") != std::string::npos)
  {
    std::string field;
    for (char ch : line)
    {
      if (ch == ',' || ch == ';')
      {
        fields.push_back(trim(field));
        field.clear();
      }
      else
      {
        field.push_back(ch);
      }
    }
    fields.push_back(trim(field));
  }
  else
  {
    std::istringstream words(line);
    std::string w;
    while (words >> w)
    {
      fields.push_back(w);
    }
  }
  while (!fields.empty() && fields.back().empty())
  {
    fields.pop_back();
  }
  return fields;
}

bool looksBinary(const std::string& data)
{
  const std::size_t n = std::min<std::size_t>(data.size(), 65536);
  for (std::size_t i = 0; i < n; ++i)
  {
    const unsigned char c = static_cast<unsigned char>(data[i]);
    if (c == 0 || (c < 0x20 && c != '\n' && c != '\r' && c != '\t' && c != '\v' && c != '\f'))
    {
      return true;
    }
  }
  return false;
}

void readText(const std::string& path, const std::string& data, PointFileResult& out)
{
  if (looksBinary(data))
  {
    std::ostringstream head;
    for (std::size_t i = 0; i < std::min<std::size_t>(8, data.size()); ++i)
    {
      char buf[8];
      std::snprintf(buf, sizeof(buf), "%02x", static_cast<unsigned char>(data[i]));
      head << (i ? " " : "") << buf;
    }
    throw FileError(path + ": not a point cloud (binary content that is neither PLY nor PCD; first bytes " + head.str() + ")");
  }
  out.format = "text";
  std::istringstream in(data);
  std::string line;
  std::size_t number = 0;
  bool seen_data = false;
  while (std::getline(in, line))
  {
    ++number;
    const std::string t = trim(line);
    if (t.empty() || t[0] == '#')
    {
      continue;
    }
    const std::vector<std::string> fields = splitFields(t);
    if (!seen_data)
    {
      bool any_number = false;
      for (const auto& f : fields)
      {
        double v;
        any_number = any_number || parseNumber(f, v);
      }
      if (!any_number)
      {
        seen_data = true;  // one header line of words is allowed
        continue;
      }
    }
    seen_data = true;
    if (fields.size() < 3)
    {
      throw FileError(path + ": line " + std::to_string(number) + " has " + std::to_string(fields.size()) +
                      " value(s); a point needs at least 3 (x y z)");
    }
    double xyz[3];
    for (int k = 0; k < 3; ++k)
    {
      if (!parseNumber(fields[static_cast<std::size_t>(k)], xyz[k]))
      {
        throw FileError(path + ": line " + std::to_string(number) + ": field " + std::to_string(k + 1) + " ('" +
                        fields[static_cast<std::size_t>(k)].substr(0, 20) + "') is not a number");
      }
    }
    out.n_columns = std::max(out.n_columns, fields.size());
    ++out.n_rows;
    out.points.emplace_back(static_cast<float>(xyz[0]), static_cast<float>(xyz[1]), static_cast<float>(xyz[2]));
  }
}


struct PlyProperty
{
  std::string name;
  std::string type;
  bool list = false;
  std::string count_type;
};

struct PlyElement
{
  std::string name;
  std::size_t count = 0;
  std::vector<PlyProperty> props;
};

std::size_t plyTypeSize(const std::string& path, const std::string& t)
{
  if (t == "char" || t == "uchar" || t == "int8" || t == "uint8")
  {
    return 1;
  }
  if (t == "short" || t == "ushort" || t == "int16" || t == "uint16")
  {
    return 2;
  }
  if (t == "int" || t == "uint" || t == "float" || t == "int32" || t == "uint32" || t == "float32")
  {
    return 4;
  }
  if (t == "double" || t == "float64" || t == "int64" || t == "uint64")
  {
    return 8;
  }
  throw FileError(path + ": PLY property type '" + t + "' is unknown");
}

double plyValue(const std::string& t, const unsigned char* p, bool big_endian)
{
  unsigned char b[8];
  const std::size_t n = (t == "char" || t == "uchar" || t == "int8" || t == "uint8") ? 1
                        : (t == "short" || t == "ushort" || t == "int16" || t == "uint16") ? 2
                        : (t == "double" || t == "float64" || t == "int64" || t == "uint64") ? 8 : 4;
  for (std::size_t i = 0; i < n; ++i)
  {
    b[i] = big_endian ? p[n - 1 - i] : p[i];
  }
  auto as = [&b](auto v) {
    std::memcpy(&v, b, sizeof(v));
    return static_cast<double>(v);
  };
  if (t == "char" || t == "int8") return as(std::int8_t());
  if (t == "uchar" || t == "uint8") return as(std::uint8_t());
  if (t == "short" || t == "int16") return as(std::int16_t());
  if (t == "ushort" || t == "uint16") return as(std::uint16_t());
  if (t == "int" || t == "int32") return as(std::int32_t());
  if (t == "uint" || t == "uint32") return as(std::uint32_t());
  if (t == "float" || t == "float32") return as(float());
  if (t == "double" || t == "float64") return as(double());
  if (t == "int64") return as(std::int64_t());
  return as(std::uint64_t());
}

void readPly(const std::string& path, const std::string& data, PointFileResult& out)
{
  out.format = "ply";
  std::size_t pos = 0;
  std::string encoding;
  std::vector<PlyElement> elements;
  bool ended = false;
  std::size_t number = 0;
  while (pos < data.size())
  {
    std::size_t eol = data.find('\n', pos);
    if (eol == std::string::npos)
    {
      break;
    }
    const std::string line = trim(data.substr(pos, eol - pos));
    pos = eol + 1;
    ++number;
    if (number == 1)
    {
      continue;  // "ply"
    }
    std::istringstream words(line);
    std::string key;
    words >> key;
    if (key.empty() || key == "comment" || key == "obj_info")
    {
      continue;
    }
    if (key == "end_header")
    {
      ended = true;
      break;
    }
    if (key == "format")
    {
      words >> encoding;
    }
    else if (key == "element")
    {
      PlyElement e;
      long long count = -1;
      words >> e.name >> count;
      if (e.name.empty() || count < 0 || words.fail())
      {
        throw FileError(path + ": PLY header line " + std::to_string(number) + " is malformed: '" + line + "'");
      }
      e.count = static_cast<std::size_t>(count);
      elements.push_back(e);
    }
    else if (key == "property")
    {
      if (elements.empty())
      {
        throw FileError(path + ": PLY header line " + std::to_string(number) + ": property before any element");
      }
      PlyProperty prop;
      std::string first;
      words >> first;
      if (first == "list")
      {
        prop.list = true;
        words >> prop.count_type >> prop.type >> prop.name;
        plyTypeSize(path, prop.count_type);
      }
      else
      {
        prop.type = first;
        words >> prop.name;
      }
      if (prop.name.empty())
      {
        throw FileError(path + ": PLY header line " + std::to_string(number) + " is malformed: '" + line + "'");
      }
      plyTypeSize(path, prop.type);
      elements.back().props.push_back(prop);
    }
    else
    {
      throw FileError(path + ": PLY header line " + std::to_string(number) + " is not a header entry: '" +
                      line.substr(0, 60) + "'");
    }
  }
  if (!ended)
  {
    throw FileError(path + ": PLY header has no end_header line");
  }
  if (encoding != "ascii" && encoding != "binary_little_endian" && encoding != "binary_big_endian")
  {
    throw FileError(path + ": PLY format '" + encoding + "' is unknown (expected ascii, binary_little_endian or binary_big_endian)");
  }
  std::size_t vi = elements.size();
  for (std::size_t i = 0; i < elements.size(); ++i)
  {
    if (elements[i].name == "vertex")
    {
      vi = i;
      break;
    }
  }
  if (vi == elements.size())
  {
    throw FileError(path + ": PLY file has no vertex element");
  }
  const PlyElement& vertex = elements[vi];
  int idx[3] = { -1, -1, -1 };
  for (std::size_t k = 0; k < vertex.props.size(); ++k)
  {
    for (int a = 0; a < 3; ++a)
    {
      if (vertex.props[k].name == std::string(1, "xyz"[a]))
      {
        if (vertex.props[k].list)
        {
          throw FileError(path + ": PLY vertex property " + vertex.props[k].name + " is a list, not a number");
        }
        idx[a] = static_cast<int>(k);
      }
    }
  }
  if (idx[0] < 0 || idx[1] < 0 || idx[2] < 0)
  {
    throw FileError(path + ": PLY vertex element lacks x, y or z properties");
  }
  out.n_columns = vertex.props.size();
  out.points.reserve(vertex.count);
  if (encoding == "ascii")
  {
    std::istringstream in(data.substr(pos));
    std::string line;
    std::size_t skip = 0;
    for (std::size_t i = 0; i < vi; ++i)
    {
      skip += elements[i].count;
    }
    std::size_t row = 0;
    while (out.points.size() < vertex.count && std::getline(in, line))
    {
      ++number;
      const std::string t = trim(line);
      if (t.empty())
      {
        continue;
      }
      if (row++ < skip)
      {
        continue;
      }
      std::vector<std::string> fields = splitFields(t);
      double v[3];
      for (int a = 0; a < 3; ++a)
      {
        const std::size_t k = static_cast<std::size_t>(idx[a]);
        if (k >= fields.size() || !parseNumber(fields[k], v[a]))
        {
          throw FileError(path + ": line " + std::to_string(number) + ": vertex row does not match the PLY header");
        }
      }
      out.points.emplace_back(static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2]));
    }
  }
  else
  {
    const bool big = encoding == "binary_big_endian";
    const unsigned char* base = reinterpret_cast<const unsigned char*>(data.data());
    std::size_t off = pos;
    auto need = [&](std::size_t n) {
      if (data.size() - off < n || off > data.size())
      {
        throw FileError(path + ": " + encoding + " PLY data is truncated");
      }
    };
    for (std::size_t e = 0; e <= vi; ++e)
    {
      const PlyElement& el = elements[e];
      for (std::size_t i = 0; i < el.count; ++i)
      {
        double v[3] = { 0.0, 0.0, 0.0 };
        for (std::size_t k = 0; k < el.props.size(); ++k)
        {
          const PlyProperty& p = el.props[k];
          if (p.list)
          {
            const std::size_t cs = plyTypeSize(path, p.count_type);
            need(cs);
            const double count = plyValue(p.count_type, base + off, big);
            off += cs;
            if (!(count >= 0.0) || count > 1e9)
            {
              throw FileError(path + ": " + encoding + " PLY list length is invalid");
            }
            const std::size_t bytes = static_cast<std::size_t>(count) * plyTypeSize(path, p.type);
            need(bytes);
            off += bytes;
            continue;
          }
          const std::size_t size = plyTypeSize(path, p.type);
          need(size);
          if (e == vi)
          {
            for (int a = 0; a < 3; ++a)
            {
              if (static_cast<int>(k) == idx[a])
              {
                v[a] = plyValue(p.type, base + off, big);
              }
            }
          }
          off += size;
        }
        if (e == vi)
        {
          out.points.emplace_back(static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2]));
        }
      }
    }
  }
  if (out.points.size() < vertex.count)
  {
    throw FileError(path + ": PLY data is truncated: " + std::to_string(out.points.size()) + " of " +
                    std::to_string(vertex.count) + " vertices present");
  }
  out.n_rows = out.points.size();
}


void readPcd(const std::string& path, PointFileResult& out)
{
  out.format = "pcd";
  pcl::PCLPointCloud2 blob;
  pcl::PCDReader reader;
  if (reader.read(path, blob) < 0)
  {
    throw FileError(path + ": PCL could not read this PCD file (malformed header or data)");
  }
  bool has[3] = { false, false, false };
  for (const auto& f : blob.fields)
  {
    for (int a = 0; a < 3; ++a)
    {
      has[a] = has[a] || f.name == std::string(1, "xyz"[a]);
    }
  }
  if (!has[0] || !has[1] || !has[2])
  {
    throw FileError(path + ": PCD file has no x, y and z fields");
  }
  out.n_columns = blob.fields.size();
  pcl::PointCloud<pcl::PointXYZ> cloud;
  pcl::fromPCLPointCloud2(blob, cloud);
  out.points.reserve(cloud.size());
  for (const auto& p : cloud.points)
  {
    out.points.emplace_back(p.x, p.y, p.z);
  }
  out.n_rows = out.points.size();
}

bool looksPcd(const std::string& data)
{
  std::istringstream in(data.substr(0, 4096));
  std::string line;
  for (int i = 0; i < 20 && std::getline(in, line); ++i)
  {
    const std::string t = trim(line);
    if (t.empty())
    {
      continue;
    }
    if (t[0] == '#')
    {
      if (t.find(".PCD") != std::string::npos)
      {
        return true;
      }
      continue;
    }
    return t.rfind("VERSION", 0) == 0 || t.rfind("FIELDS", 0) == 0;
  }
  return false;
}

std::string lowerExtension(const std::string& path)
{
  const auto dot = path.find_last_of('.');
  const auto slash = path.find_last_of('/');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash))
  {
    return "";
  }
  std::string ext = path.substr(dot);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}
}  // namespace

PointFileResult readPointFile(const std::string& path)
{
  PointFileResult out;
  try
  {
    std::ifstream in(path.c_str(), std::ios_base::in | std::ios_base::binary);
    if (!in.is_open())
    {
      throw FileError(path + ": cannot open the file");
    }
    const std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (in.bad())
    {
      throw FileError(path + ": read error");
    }
    const std::string ext = lowerExtension(path);
    if (data.rfind("ply\n", 0) == 0 || data.rfind("ply\r\n", 0) == 0)
    {
      readPly(path, data, out);
    }
    else if (looksPcd(data))
    {
      readPcd(path, out);
    }
    else if (ext == ".ply" || ext == ".pcd")
    {
      throw FileError(path + ": not a " + ext.substr(1) + " file (no " + (ext == ".ply" ? "'ply'" : "'VERSION'/'FIELDS'") +
                      " line at the start)");
    }
    else
    {
      readText(path, data, out);
    }
    if (out.points.empty())
    {
      throw FileError(path + ": no points");
    }
    PointList finite;
    finite.reserve(out.points.size());
    for (const auto& p : out.points)
    {
      if (p.allFinite())
      {
        finite.push_back(p);
      }
    }
    out.n_non_finite = out.points.size() - finite.size();
    if (finite.empty())
    {
      throw FileError(path + ": no points: all " + std::to_string(out.points.size()) +
                      " rows have a NaN or infinite coordinate");
    }
    out.points.swap(finite);
    out.ok = true;
  }
  catch (const std::exception& e)
  {
    out = PointFileResult();
    out.error = e.what();
    if (out.error.rfind(path, 0) != 0)
    {
      out.error = path + ": " + out.error;
    }
  }
  return out;
}

}  // namespace sparse_nav
