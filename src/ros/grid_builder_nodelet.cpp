#include "sparse_nav/ros/grid_builder_nodelet.h"

#include <chrono>
#include <exception>
#include <limits>
#include <utility>

#include <map_msgs/OccupancyGridUpdate.h>
#include <nav_msgs/OccupancyGrid.h>
#include <visualization_msgs/Marker.h>

#include "sparse_nav/ros/conversions.h"
#include "sparse_nav/ros/node_utils.h"

namespace sparse_nav
{
void GridBuilderNodelet::onInit()
{
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  loadParam(pnh, "resolution_m", config_.resolution_m);
  loadParam(pnh, "tile_size_cells", config_.tile_size_cells);
  loadParam(pnh, "padding_m", config_.padding_m);
  loadParam(pnh, "max_cells", config_.max_cells);
  loadParam(pnh, "alpha_m", config_.alpha.alpha_m);
  loadParam(pnh, "auto_alpha", config_.alpha.auto_alpha);
  loadParam(pnh, "max_auto_alpha_m", config_.alpha.max_auto_alpha_m);
  loadParam(pnh, "clear_segment_min_rays", config_.clear_segment_min_rays);
  loadParam(pnh, "map_frame", map_frame_);
  loadParam(pnh, "camera_frame", camera_frame_);
  loadParam(pnh, "trajectory_spacing_m", trajectory_spacing_m_);
  loadParam(pnh, "max_rays", max_rays_);
  loadParam(pnh, "reset_on_map_switch", reset_on_map_switch_);
  config_.validate();
  if (!(trajectory_spacing_m_ > 0.0) || max_rays_ == 0)
    throw std::invalid_argument("trajectory_spacing_m and max_rays must be > 0");

  builder_.reset(new GridBuilder(config_));
  tf_buffer_.reset(new tf2_ros::Buffer(ros::Duration(30.0)));
  tf_listener_.reset(new tf2_ros::TransformListener(*tf_buffer_, nh));
  map_pub_ = nh.advertise<nav_msgs::OccupancyGrid>("map", 1, true);
  update_pub_ = nh.advertise<map_msgs::OccupancyGridUpdate>("map_updates", 10);
  shapes_pub_ = nh.advertise<visualization_msgs::Marker>("grid_builder/alpha_shapes", 1, true);
  diag_pub_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 5);
  reset_srv_ = pnh.advertiseService("reset", &GridBuilderNodelet::onReset, this);
  floor_sub_ = nh.subscribe("cloud/floor", 2, &GridBuilderNodelet::onFloor, this);
  obstacles_sub_ = nh.subscribe("cloud/obstacles", 2, &GridBuilderNodelet::onObstacles, this);
  state_sub_ = nh.subscribe("slam/state", 20, &GridBuilderNodelet::onSlamState, this);
}

void GridBuilderNodelet::onSlamState(const SlamStateConstPtr& msg)
{
  std::lock_guard<std::mutex> lock(mutex_);
  if (!map_switch_.switched(msg->map_index) || !reset_on_map_switch_)
    return;
  // Camera positions and cells of the old map are in another anchoring: the grid starts afresh.
  resetLocked();
  NODELET_INFO("grid_builder: SLAM map %u, grid starts afresh", msg->map_index);
}

void GridBuilderNodelet::diagnose(bool ok, const std::string& message)
{
  const OccupancyGrid& grid = builder_->grid();
  publishDiagnostics(diag_pub_, "grid_builder", ok, message,
                     { { "width", std::to_string(grid.width) },
                       { "height", std::to_string(grid.height) },
                       { "occupied_cells", std::to_string(grid.count(OccupancyGrid::kOccupied)) },
                       { "free_cells", std::to_string(grid.count(OccupancyGrid::kFree)) },
                       { "recomputed_tiles", std::to_string(last_update_.recomputed_tiles.size()) },
                       { "alpha_m", std::to_string(last_update_.alpha_m) },
                       { "camera_positions", std::to_string(trajectory_.size()) },
                       { "clouds_rejected", std::to_string(n_rejected_) },
                       { "last_ms", std::to_string(last_ms_) } });
}

void GridBuilderNodelet::rememberCamera(const ros::Time& stamp)
{
  Eigen::Vector3d origin;
  std::string error;
  if (!lookupOrigin(*tf_buffer_, map_frame_, camera_frame_, stamp, origin, &error))
  {
    NODELET_WARN_THROTTLE(5.0, "grid_builder: no TF %s -> %s (%s); free space not updated", map_frame_.c_str(),
                          camera_frame_.c_str(), error.c_str());
    return;
  }
  const Eigen::Vector2d p = origin.head<2>();
  if (trajectory_.empty() || (trajectory_.back() - p).norm() >= trajectory_spacing_m_)
    trajectory_.push_back(p);
}

void GridBuilderNodelet::onFloor(const sensor_msgs::PointCloud2ConstPtr& msg)
{
  try
  {
    std::lock_guard<std::mutex> lock(mutex_);
    PointList points;
    std::string error;
    if (msg->header.frame_id != map_frame_ || !cloudToPoints(*msg, points, &error))
    {
      NODELET_ERROR_THROTTLE(5.0, "grid_builder: ignoring floor cloud (%s)",
                             error.empty() ? ("frame " + msg->header.frame_id).c_str() : error.c_str());
      return;
    }
    floor_points_ = points;
  }
  catch (const std::exception& e)
  {
    NODELET_ERROR_THROTTLE(5.0, "grid_builder: %s", e.what());
  }
}

void GridBuilderNodelet::onObstacles(const sensor_msgs::PointCloud2ConstPtr& msg)
{
  try
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto start = std::chrono::steady_clock::now();
    PointList points;
    std::string error;
    if (msg->header.frame_id != map_frame_)
      error = "cloud in frame '" + msg->header.frame_id + "', expected '" + map_frame_ + "'";
    else
      cloudToPoints(*msg, points, &error);
    if (!error.empty())
    {
      ++n_rejected_;
      NODELET_ERROR_THROTTLE(5.0, "grid_builder: %s; keeping the last map", error.c_str());
      diagnose(false, error);
      return;
    }
    rememberCamera(msg->header.stamp);
    PointList2D obstacles;
    obstacles.reserve(points.size());
    for (const auto& p : points)
      obstacles.emplace_back(p.x(), p.y());
    // Each observed point proves the space between it and the nearest camera position free.
    std::vector<FreeRay> rays;
    if (!trajectory_.empty())
    {
      const std::size_t total = points.size() + floor_points_.size();
      const std::size_t stride = total > max_rays_ ? (total + max_rays_ - 1) / max_rays_ : 1;
      std::size_t i = 0;
      auto addRay = [&](const Eigen::Vector3f& p) {
        if (i++ % stride != 0)
          return;
        const Eigen::Vector2d end(p.x(), p.y());
        const Eigen::Vector2d* nearest = &trajectory_.front();
        double best = std::numeric_limits<double>::infinity();
        for (const auto& c : trajectory_)
        {
          const double d = (c - end).squaredNorm();
          if (d < best)
          {
            best = d;
            nearest = &c;
          }
        }
        rays.push_back({ *nearest, end });
      };
      for (const auto& p : points)
        addRay(p);
      for (const auto& p : floor_points_)
        addRay(p);
    }
    const GridUpdate update = builder_->update(obstacles, std::move(rays));
    if (!update.ok)
    {
      ++n_rejected_;
      NODELET_ERROR_THROTTLE(5.0, "grid_builder: %s; keeping the last map", update.status.c_str());
      diagnose(false, update.status);
      return;
    }
    last_update_ = update;
    std_msgs::Header header = msg->header;
    if (update.full_rebuild)
    {
      map_pub_.publish(gridToMsg(builder_->grid(), header));
      publishShapes(header);
    }
    else if (auto patch = gridUpdateToMsg(builder_->grid(), update, header))
    {
      update_pub_.publish(patch);
      // Latecomers get the whole map from the latched topic, so keep it current too.
      map_pub_.publish(gridToMsg(builder_->grid(), header));
    }
    last_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    diagnose(true, update.status);
  }
  catch (const std::exception& e)
  {
    NODELET_ERROR_THROTTLE(5.0, "grid_builder: %s; keeping the last map", e.what());
  }
}

void GridBuilderNodelet::publishShapes(const std_msgs::Header& header)
{
  visualization_msgs::Marker lines;
  lines.header = header;
  lines.ns = "alpha_shapes";
  lines.type = visualization_msgs::Marker::LINE_LIST;
  lines.pose.orientation.w = 1.0;
  lines.scale.x = 0.03;
  lines.color.r = 1.0f;
  lines.color.g = 0.5f;
  lines.color.a = 1.0f;
  auto add = [&lines](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    geometry_msgs::Point p, q;
    p.x = a.x();
    p.y = a.y();
    q.x = b.x();
    q.y = b.y();
    lines.points.push_back(p);
    lines.points.push_back(q);
  };
  const AlphaShapeResult& shape = builder_->lastShape();
  for (const auto& ring : shape.rings)
    for (std::size_t i = 0; i < ring.size(); ++i)
      add(ring[i], ring[(i + 1) % ring.size()]);
  for (const auto& segment : shape.segments)
    add(segment.first, segment.second);
  shapes_pub_.publish(lines);
}

bool GridBuilderNodelet::onReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res)
{
  std::lock_guard<std::mutex> lock(mutex_);
  resetLocked();
  res.success = true;
  res.message = "grid cleared";
  return true;
}

void GridBuilderNodelet::resetLocked()
{
  builder_->reset();
  trajectory_.clear();
  floor_points_.clear();
}
}  // namespace sparse_nav
