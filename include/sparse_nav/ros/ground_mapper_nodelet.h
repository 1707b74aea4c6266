#ifndef SPARSE_NAV_ROS_GROUND_MAPPER_NODELET_H
#define SPARSE_NAV_ROS_GROUND_MAPPER_NODELET_H

#include <memory>
#include <mutex>
#include <string>

#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include "sparse_nav/MapFile.h"
#include "sparse_nav/SlamState.h"
#include "sparse_nav/core/ground_mapper.h"
#include "sparse_nav/ros/node_utils.h"

namespace sparse_nav
{
/**
 * @brief ground_mapper: a shell around the core GroundMapper (floor plane, OctoMap octree with
 * free space ray-cast from the camera, the obstacle cloud between the floor band and the ceiling
 * band, less the points in proven free space), the same object build_grid runs.
 *
 * Subscribes `cloud/filtered` (map frame, metres) and TF map -> camera; publishes
 * `cloud/obstacles` and `cloud/floor` (map frame), `floor_plane` (sparse_nav/FloorEstimate),
 * `ground_mapper/floor_marker` and `ground_mapper/occupied_voxels` (visualization_msgs), and
 * `/diagnostics`. Subscribes `slam/state` to start afresh when the SLAM map changes. Services
 * `~save` / `~load` (sparse_nav/MapFile: a name in map_dir, .bt) and `~reset` (std_srvs/Trigger).
 */
class GroundMapperNodelet : public nodelet::Nodelet
{
public:
  void onInit() override;

private:
  void onCloud(const sensor_msgs::PointCloud2ConstPtr& msg);
  void onSlamState(const SlamStateConstPtr& msg);
  bool onSave(MapFile::Request& req, MapFile::Response& res);
  bool onLoad(MapFile::Request& req, MapFile::Response& res);
  bool onReset(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool cameraPosition(const ros::Time& stamp, Eigen::Vector3d& position);
  void publishMarkers(const std_msgs::Header& header);
  void diagnose(bool ok, const std::string& message);
  std::string mapPath(const std::string& name) const;

  std::string map_frame_ = "map";
  std::string camera_frame_ = "camera_optical";
  std::string map_dir_;
  double markers_period_s_ = 1.0;
  bool reset_on_map_switch_ = true;
  MapSwitchDetector map_switch_;

  std::unique_ptr<GroundMapper> mapper_;
  Eigen::Vector3d last_camera_ = Eigen::Vector3d::Zero();
  bool has_camera_ = false;
  ros::Time last_markers_;
  std::size_t n_obstacles_ = 0, n_freed_ = 0, n_rejected_ = 0;
  double last_ms_ = 0.0;

  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  ros::Subscriber sub_, state_sub_;
  ros::Publisher obstacles_pub_, floor_points_pub_, plane_pub_, floor_marker_pub_, voxels_pub_, diag_pub_;
  ros::ServiceServer save_srv_, load_srv_, reset_srv_;
  std::mutex mutex_;
};
}  // namespace sparse_nav

#endif  // SPARSE_NAV_ROS_GROUND_MAPPER_NODELET_H
