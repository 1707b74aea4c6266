#ifndef SPARSE_NAV_ROS_CLOUD_FILTER_NODELET_H
#define SPARSE_NAV_ROS_CLOUD_FILTER_NODELET_H

#include <memory>
#include <mutex>
#include <string>

#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>

#include "sparse_nav/core/cloud_filters.h"

namespace sparse_nav
{
/**
 * @brief cloud_filter: finite-point and range guard and voxel grid on the metric SLAM cloud. The
 * density filter runs in ground_mapper, after the floor search: sparse floors must reach it.
 *
 * Subscribes `slam/points` (sensor_msgs/PointCloud2, metres, any frame); publishes
 * `cloud/filtered` in the same frame and `/diagnostics`. The voxel grid is updated in the voxels
 * of the points that moved since the last cloud (IncrementalVoxelFilter). A bad cloud is refused
 * with a throttled error and the last good output stays the latest published.
 */
class CloudFilterNodelet : public nodelet::Nodelet
{
public:
  void onInit() override;

private:
  void onCloud(const sensor_msgs::PointCloud2ConstPtr& msg);
  void diagnose(bool ok, const std::string& message);

  PointGuardConfig guard_config_;
  VoxelFilterConfig voxel_config_;
  bool voxel_enabled_ = true;
  int max_points_ = 5000000;  ///< larger clouds are refused (memory and latency bound)
  std::unique_ptr<IncrementalVoxelFilter> voxel_;

  ros::Subscriber sub_;
  ros::Publisher pub_;
  ros::Publisher diag_pub_;
  std::mutex mutex_;
  std::size_t n_in_ = 0, n_out_ = 0, n_changed_ = 0, n_rejected_ = 0;
  double last_ms_ = 0.0;
};
}  // namespace sparse_nav

#endif  // SPARSE_NAV_ROS_CLOUD_FILTER_NODELET_H
