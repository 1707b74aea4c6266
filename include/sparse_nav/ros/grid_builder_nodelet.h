#ifndef SPARSE_NAV_ROS_GRID_BUILDER_NODELET_H
#define SPARSE_NAV_ROS_GRID_BUILDER_NODELET_H

#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include "sparse_nav/SlamState.h"
#include "sparse_nav/core/grid_builder.h"
#include "sparse_nav/ros/node_utils.h"

namespace sparse_nav
{
/**
 * @brief grid_builder: CGAL alpha shapes over the obstacle slice, rasterised into an occupancy
 * grid; free cells from 2D rays between the camera's past positions and the observed points.
 *
 * Subscribes `cloud/obstacles` and `cloud/floor` (map frame) and TF map -> camera; publishes
 * `map` (nav_msgs/OccupancyGrid, latched), `map_updates` (map_msgs/OccupancyGridUpdate, only the
 * changed window), `grid_builder/alpha_shapes` (visualization_msgs/Marker) and `/diagnostics`;
 * service `~reset` (std_srvs/Trigger). Subscribes `slam/state` to start afresh when the SLAM map
 * changes.
 */
class GridBuilderNodelet : public nodelet::Nodelet
{
public:
  void onInit() override;

private:
  void onObstacles(const sensor_msgs::PointCloud2ConstPtr& msg);
  void onFloor(const sensor_msgs::PointCloud2ConstPtr& msg);
  void onSlamState(const SlamStateConstPtr& msg);
  void resetLocked();
  bool onReset(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  void rememberCamera(const ros::Time& stamp);
  void publishShapes(const std_msgs::Header& header);
  void diagnose(bool ok, const std::string& message);

  GridBuilderConfig config_;
  std::string map_frame_ = "map";
  std::string camera_frame_ = "camera_optical";
  bool reset_on_map_switch_ = true;
  MapSwitchDetector map_switch_;
  double trajectory_spacing_m_ = 0.25;  ///< a camera position is kept when this far from the last kept one
  std::size_t max_rays_ = 200000;       ///< rays per update at most (every k-th point beyond)

  std::unique_ptr<GridBuilder> builder_;
  std::vector<Eigen::Vector2d> trajectory_;
  PointList floor_points_;
  GridUpdate last_update_;
  std::size_t n_rejected_ = 0;
  double last_ms_ = 0.0;

  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  ros::Subscriber obstacles_sub_, floor_sub_, state_sub_;
  ros::Publisher map_pub_, update_pub_, shapes_pub_, diag_pub_;
  ros::ServiceServer reset_srv_;
  std::mutex mutex_;
};
}  // namespace sparse_nav

#endif  // SPARSE_NAV_ROS_GRID_BUILDER_NODELET_H
