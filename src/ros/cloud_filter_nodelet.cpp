#include "sparse_nav/ros/cloud_filter_nodelet.h"

#include <chrono>
#include <exception>
#include <utility>

#include "sparse_nav/ros/conversions.h"
#include "sparse_nav/ros/node_utils.h"

namespace sparse_nav
{
void CloudFilterNodelet::onInit()
{
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  loadParam(pnh, "max_abs_coordinate_m", guard_config_.max_abs_coordinate);
  loadParam(pnh, "voxel_enabled", voxel_enabled_);
  loadParam(pnh, "leaf_size_m", voxel_config_.leaf_size_m);
  loadParam(pnh, "max_points", max_points_);
  guard_config_.validate();
  voxel_config_.validate();
  voxel_.reset(new IncrementalVoxelFilter(voxel_config_, voxel_enabled_));

  pub_ = nh.advertise<sensor_msgs::PointCloud2>("cloud/filtered", 2);
  diag_pub_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 5);
  sub_ = nh.subscribe("slam/points", 2, &CloudFilterNodelet::onCloud, this);
  NODELET_INFO("cloud_filter: voxel grid %s, leaf %.3f m", voxel_enabled_ ? "on" : "off", voxel_config_.leaf_size_m);
}

void CloudFilterNodelet::diagnose(bool ok, const std::string& message)
{
  publishDiagnostics(diag_pub_, "cloud_filter", ok, message,
                     { { "points_in", std::to_string(n_in_) },
                       { "points_out", std::to_string(n_out_) },
                     { "points_changed", std::to_string(n_changed_) },
                       { "clouds_rejected", std::to_string(n_rejected_) },
                       { "last_ms", std::to_string(last_ms_) } });
}

void CloudFilterNodelet::onCloud(const sensor_msgs::PointCloud2ConstPtr& msg)
{
  // An exception escaping a nodelet callback takes the whole manager (and SLAM) down.
  try
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto start = std::chrono::steady_clock::now();
    const std::size_t n = static_cast<std::size_t>(msg->width) * msg->height;
    if (n > static_cast<std::size_t>(max_points_))
    {
      ++n_rejected_;
      NODELET_ERROR_THROTTLE(5.0, "cloud_filter: refusing a cloud of %zu points (max_points %d); keeping "
                                  "the last output", n, max_points_);
      diagnose(false, "cloud too large");
      return;
    }
    PointList points;
    std::string error;
    if (!cloudToPoints(*msg, points, &error))
    {
      ++n_rejected_;
      NODELET_ERROR_THROTTLE(5.0, "cloud_filter: %s; keeping the last output", error.c_str());
      diagnose(false, error);
      return;
    }
    PointGuardStats guard_stats;
    points = PointGuard(guard_config_).apply(points, &guard_stats);
    if (guard_stats.n_non_finite + guard_stats.n_out_of_range > 0)
      NODELET_WARN_THROTTLE(5.0, "cloud_filter: dropped %zu non-finite and %zu out-of-range points",
                            guard_stats.n_non_finite, guard_stats.n_out_of_range);
    if (points.empty())
    {
      ++n_rejected_;
      NODELET_WARN_THROTTLE(5.0, "cloud_filter: no usable point in the cloud; keeping the last output");
      diagnose(false, "empty cloud");
      return;
    }
    // SLAM map points keep their order between messages: only the voxels of those that moved change.
    const PointList& filtered = voxel_->apply(std::move(points));
    n_in_ = n;
    n_out_ = filtered.size();
    n_changed_ = voxel_->numChanged();
    last_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    pub_.publish(pointsToCloud(filtered, msg->header));
    diagnose(true, "ok");
  }
  catch (const std::exception& e)
  {
    voxel_->clear();  // the next cloud is taken whole
    NODELET_ERROR_THROTTLE(5.0, "cloud_filter: %s; keeping the last output", e.what());
  }
}
}  // namespace sparse_nav
