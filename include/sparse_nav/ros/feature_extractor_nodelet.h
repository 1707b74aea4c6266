#ifndef SPARSE_NAV_ROS_FEATURE_EXTRACTOR_NODELET_H
#define SPARSE_NAV_ROS_FEATURE_EXTRACTOR_NODELET_H

#include <memory>
#include <mutex>
#include <string>

#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/LaserScan.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include "sparse_nav/core/line_features.h"
#include "sparse_nav/Features.h"

namespace sparse_nav
{
/**
 * @brief feature_extractor: walls, doors, corners and corridors (seed 002) from a virtual scan of
 * the obstacle cloud around the robot, or from a real laser scan.
 *
 * input "cloud": subscribes `cloud/obstacles` (PointCloud2 in map_frame, z up) and TF
 * map_frame -> base_frame, and publishes in map_frame. input "scan": subscribes `scan`
 * (sensor_msgs/LaserScan) and publishes in the scan's frame. Publishes `features`
 * (sparse_nav/Features), `features/markers` (visualization_msgs/MarkerArray) and `/diagnostics`.
 * Refused input gives a Features message with ok false and the reason; markers keep the last good
 * features.
 */
class FeatureExtractorNodelet : public nodelet::Nodelet
{
public:
  void onInit() override;

private:
  void onCloud(const sensor_msgs::PointCloud2ConstPtr& msg);
  void onScan(const sensor_msgs::LaserScanConstPtr& msg);
  void publish(const ScanFeatures& features, const std_msgs::Header& header, const Pose2D& robot, double ms);
  void refuse(const std_msgs::Header& header, const std::string& reason);
  void publishMarkers(const ScanFeatures& features, const std_msgs::Header& header);
  void diagnose(bool ok, const std::string& message);

  LineFeatureConfig config_;
  VirtualScanConfig virtual_config_;
  std::string input_ = "cloud";
  std::string map_frame_ = "map";
  std::string base_frame_ = "base_link";

  std::unique_ptr<LineFeatureExtractor> extractor_;
  std::size_t n_refused_ = 0;
  std::size_t n_walls_ = 0, n_doors_ = 0, n_corners_ = 0, n_corridors_ = 0;
  double last_ms_ = 0.0;

  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  ros::Subscriber sub_;
  ros::Publisher features_pub_, markers_pub_, diag_pub_;
  std::mutex mutex_;
};
}  // namespace sparse_nav

#endif  // SPARSE_NAV_ROS_FEATURE_EXTRACTOR_NODELET_H
