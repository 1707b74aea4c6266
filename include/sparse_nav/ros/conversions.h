#ifndef SPARSE_NAV_ROS_CONVERSIONS_H
#define SPARSE_NAV_ROS_CONVERSIONS_H

#include <string>

#include <map_msgs/OccupancyGridUpdate.h>
#include <nav_msgs/OccupancyGrid.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/Header.h>

#include "sparse_nav/core/grid_builder.h"
#include "sparse_nav/core/types.h"

namespace sparse_nav
{
/**
 * @brief Reads the x/y/z fields of a PointCloud2 (any numeric type, either endianness).
 * @param error set to what is wrong when false is returned (no x/y/z, truncated data, ...)
 * @return false when the message cannot be read as points; `points` is then left empty
 */
bool cloudToPoints(const sensor_msgs::PointCloud2& msg, PointList& points, std::string* error);

/// @brief A dense x/y/z float32 PointCloud2 of the points, with the given header.
sensor_msgs::PointCloud2Ptr pointsToCloud(const PointList& points, const std_msgs::Header& header);

/// @brief nav_msgs/OccupancyGrid of a core grid (same cell layout and values).
nav_msgs::OccupancyGridPtr gridToMsg(const OccupancyGrid& grid, const std_msgs::Header& header);

/// @brief The changed window of an update, or nullptr when no cell changed.
map_msgs::OccupancyGridUpdatePtr gridUpdateToMsg(const OccupancyGrid& grid, const GridUpdate& update,
                                                 const std_msgs::Header& header);
}  // namespace sparse_nav

#endif  // SPARSE_NAV_ROS_CONVERSIONS_H
