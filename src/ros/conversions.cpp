#include "sparse_nav/ros/conversions.h"

#include <cmath>
#include <cstring>

namespace sparse_nav
{
namespace
{
std::size_t fieldSize(std::uint8_t datatype)
{
  switch (datatype)
  {
    case sensor_msgs::PointField::INT8:
    case sensor_msgs::PointField::UINT8: return 1;
    case sensor_msgs::PointField::INT16:
    case sensor_msgs::PointField::UINT16: return 2;
    case sensor_msgs::PointField::INT32:
    case sensor_msgs::PointField::UINT32:
    case sensor_msgs::PointField::FLOAT32: return 4;
    case sensor_msgs::PointField::FLOAT64: return 8;
    default: return 0;
  }
}

bool readField(const std::uint8_t* p, std::uint8_t datatype, bool swap, double& out)
{
  std::uint8_t buf[8];
  const std::size_t size = fieldSize(datatype);
  if (size == 0)
    return false;
  for (std::size_t i = 0; i < size; ++i)
    buf[i] = swap ? p[size - 1 - i] : p[i];
  switch (datatype)
  {
    case sensor_msgs::PointField::INT8: out = static_cast<std::int8_t>(buf[0]); break;
    case sensor_msgs::PointField::UINT8: out = buf[0]; break;
    case sensor_msgs::PointField::INT16: { std::int16_t v; std::memcpy(&v, buf, 2); out = v; break; }
    case sensor_msgs::PointField::UINT16: { std::uint16_t v; std::memcpy(&v, buf, 2); out = v; break; }
    case sensor_msgs::PointField::INT32: { std::int32_t v; std::memcpy(&v, buf, 4); out = v; break; }
    case sensor_msgs::PointField::UINT32: { std::uint32_t v; std::memcpy(&v, buf, 4); out = v; break; }
    case sensor_msgs::PointField::FLOAT32: { float v; std::memcpy(&v, buf, 4); out = v; break; }
    default: { double v; std::memcpy(&v, buf, 8); out = v; break; }
  }
  return true;
}
}  // namespace

bool cloudToPoints(const sensor_msgs::PointCloud2& msg, PointList& points, std::string* error)
{
  points.clear();
  const sensor_msgs::PointField* fields[3] = { nullptr, nullptr, nullptr };
  for (const auto& f : msg.fields)
  {
    if (f.name == "x") fields[0] = &f;
    if (f.name == "y") fields[1] = &f;
    if (f.name == "z") fields[2] = &f;
  }
  if (!fields[0] || !fields[1] || !fields[2])
  {
    if (error)
      *error = "PointCloud2 has no x/y/z fields";
    return false;
  }
  const std::size_t n = static_cast<std::size_t>(msg.width) * msg.height;
  if (n == 0)
    return true;
  const std::size_t step = msg.point_step;
  for (const auto* f : fields)
  {
    const std::size_t size = fieldSize(f->datatype);
    if (size == 0 || f->offset + size > step)
    {
      if (error)
        *error = "PointCloud2 field " + f->name + (size == 0 ? " has unknown datatype " + std::to_string(f->datatype)
                                                              : std::string(" lies outside point_step"));
      return false;
    }
  }
  const std::size_t row_step = msg.row_step ? msg.row_step : step * msg.width;
  if (step == 0 || row_step < step * msg.width || msg.data.size() < row_step * (msg.height - 1) + step * msg.width)
  {
    if (error)
      *error = "PointCloud2 data holds " + std::to_string(msg.data.size()) + " bytes, too few for " +
               std::to_string(n) + " points of " + std::to_string(step) + " bytes";
    return false;
  }
  const bool swap = msg.is_bigendian;  // hosts here are little-endian
  points.reserve(n);
  for (std::uint32_t row = 0; row < msg.height; ++row)
  {
    for (std::uint32_t col = 0; col < msg.width; ++col)
    {
      const std::uint8_t* p = msg.data.data() + row * row_step + col * step;
      double v[3];
      for (int k = 0; k < 3; ++k)
      {
        if (!readField(p + fields[k]->offset, fields[k]->datatype, swap, v[k]))
        {
          if (error)
            *error = "PointCloud2 field " + fields[k]->name + " has unknown datatype " +
                     std::to_string(fields[k]->datatype);
          points.clear();
          return false;
        }
      }
      points.emplace_back(static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2]));
    }
  }
  return true;
}

sensor_msgs::PointCloud2Ptr pointsToCloud(const PointList& points, const std_msgs::Header& header)
{
  sensor_msgs::PointCloud2Ptr msg(new sensor_msgs::PointCloud2);
  msg->header = header;
  msg->height = 1;
  msg->width = static_cast<std::uint32_t>(points.size());
  const char* names[3] = { "x", "y", "z" };
  for (int k = 0; k < 3; ++k)
  {
    sensor_msgs::PointField f;
    f.name = names[k];
    f.offset = 4 * k;
    f.datatype = sensor_msgs::PointField::FLOAT32;
    f.count = 1;
    msg->fields.push_back(f);
  }
  msg->is_bigendian = false;
  msg->point_step = 12;
  msg->row_step = 12 * msg->width;
  msg->is_dense = true;
  msg->data.resize(msg->row_step);
  for (std::size_t i = 0; i < points.size(); ++i)
    std::memcpy(msg->data.data() + 12 * i, points[i].data(), 12);
  return msg;
}

nav_msgs::OccupancyGridPtr gridToMsg(const OccupancyGrid& grid, const std_msgs::Header& header)
{
  nav_msgs::OccupancyGridPtr msg(new nav_msgs::OccupancyGrid);
  msg->header = header;
  msg->info.map_load_time = header.stamp;
  msg->info.resolution = static_cast<float>(grid.resolution_m);
  msg->info.width = static_cast<std::uint32_t>(std::max(grid.width, 0));
  msg->info.height = static_cast<std::uint32_t>(std::max(grid.height, 0));
  msg->info.origin.position.x = grid.origin_x_m;
  msg->info.origin.position.y = grid.origin_y_m;
  msg->info.origin.orientation.w = 1.0;
  msg->data = grid.data;
  return msg;
}

map_msgs::OccupancyGridUpdatePtr gridUpdateToMsg(const OccupancyGrid& grid, const GridUpdate& update,
                                                 const std_msgs::Header& header)
{
  if (update.max_col <= update.min_col || update.max_row <= update.min_row)
    return nullptr;
  map_msgs::OccupancyGridUpdatePtr msg(new map_msgs::OccupancyGridUpdate);
  msg->header = header;
  msg->x = update.min_col;
  msg->y = update.min_row;
  msg->width = static_cast<std::uint32_t>(update.max_col - update.min_col);
  msg->height = static_cast<std::uint32_t>(update.max_row - update.min_row);
  msg->data.reserve(static_cast<std::size_t>(msg->width) * msg->height);
  for (int row = update.min_row; row < update.max_row; ++row)
    for (int col = update.min_col; col < update.max_col; ++col)
      msg->data.push_back(grid.at(col, row));
  return msg;
}
}  // namespace sparse_nav
