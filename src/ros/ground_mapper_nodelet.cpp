#include "sparse_nav/ros/ground_mapper_nodelet.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <visualization_msgs/Marker.h>
#include <visualization_msgs/MarkerArray.h>

#include "sparse_nav/FloorEstimate.h"
#include "sparse_nav/ros/conversions.h"
#include "sparse_nav/ros/node_utils.h"

namespace sparse_nav
{
namespace
{
bool makeDirectories(const std::string& path)
{
  std::string partial;
  for (std::size_t i = 0; i <= path.size(); ++i)
  {
    if (i == path.size() || path[i] == '/')
    {
      if (!partial.empty() && ::mkdir(partial.c_str(), 0755) != 0 && errno != EEXIST)
        return false;
    }
    if (i < path.size())
      partial += path[i];
  }
  return true;
}
}  // namespace

void GroundMapperNodelet::onInit()
{
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  // The input is the metric, z-up map frame: heights are measured from the floor plane and the
  // output stays in the map frame (no re-alignment).
  GroundMapperConfig config;
  config.align_to_floor = false;
  std::string up_axis = "z";
  loadParam(pnh, "up_axis", up_axis);
  config.floor.up_axis = axisFromString(up_axis);
  loadParam(pnh, "max_tilt_deg", config.floor.max_tilt_deg);
  loadParam(pnh, "floor_distance_threshold_m", config.floor.distance_threshold_m);
  loadParam(pnh, "floor_min_inliers", config.floor.min_inliers);
  loadParam(pnh, "floor_max_planes", config.floor.max_planes);
  loadParam(pnh, "keep_floor", config.keep_floor);
  std::string density_method = "radius";
  loadParam(pnh, "density_method", density_method);
  config.density.method = densityMethodFromString(density_method);
  loadParam(pnh, "density_radius_m", config.density.radius_m);
  loadParam(pnh, "density_min_neighbors", config.density.min_neighbors);
  loadParam(pnh, "ipcl_rounds", config.density.ipcl_rounds);
  loadParam(pnh, "floor_clearance_m", config.floor_clearance_m);
  loadParam(pnh, "ceiling_height_m", config.ceiling_height_m);
  loadParam(pnh, "octree_resolution_m", config.octree.resolution_m);
  loadParam(pnh, "free_space_resolution_m", config.octree.free_space_resolution_m);
  loadParam(pnh, "octree_max_range_m", config.octree.max_range_m);
  loadParam(pnh, "free_space_filter", config.free_space_filter);
  loadParam(pnh, "clear_hit_min_rays", config.clear_hit_min_rays);
  loadParam(pnh, "clear_cell_m", config.clear_cell_m);
  loadParam(pnh, "clear_height_tolerance_m", config.clear_height_tolerance_m);
  loadParam(pnh, "clear_range_margin", config.clear_range_margin);
  loadParam(pnh, "map_frame", map_frame_);
  loadParam(pnh, "camera_frame", camera_frame_);
  const char* home = std::getenv("HOME");
  map_dir_ = std::string(home ? home : "/tmp") + "/.ros/sparse_nav/maps";
  loadParam(pnh, "map_dir", map_dir_);
  if (map_dir_.rfind("~/", 0) == 0)
    map_dir_ = std::string(home ? home : "/tmp") + map_dir_.substr(1);
  loadParam(pnh, "markers_period_s", markers_period_s_);
  loadParam(pnh, "reset_on_map_switch", reset_on_map_switch_);
  config.validate();

  mapper_.reset(new GroundMapper(config));
  tf_buffer_.reset(new tf2_ros::Buffer(ros::Duration(30.0)));
  tf_listener_.reset(new tf2_ros::TransformListener(*tf_buffer_, nh));
  obstacles_pub_ = nh.advertise<sensor_msgs::PointCloud2>("cloud/obstacles", 2);
  floor_points_pub_ = nh.advertise<sensor_msgs::PointCloud2>("cloud/floor", 2);
  plane_pub_ = nh.advertise<FloorEstimate>("floor_plane", 2, true);
  floor_marker_pub_ = nh.advertise<visualization_msgs::Marker>("ground_mapper/floor_marker", 1, true);
  voxels_pub_ = nh.advertise<visualization_msgs::MarkerArray>("ground_mapper/occupied_voxels", 1, true);
  diag_pub_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 5);
  save_srv_ = pnh.advertiseService("save", &GroundMapperNodelet::onSave, this);
  load_srv_ = pnh.advertiseService("load", &GroundMapperNodelet::onLoad, this);
  reset_srv_ = pnh.advertiseService("reset", &GroundMapperNodelet::onReset, this);
  sub_ = nh.subscribe("cloud/filtered", 2, &GroundMapperNodelet::onCloud, this);
  state_sub_ = nh.subscribe("slam/state", 20, &GroundMapperNodelet::onSlamState, this);
}

void GroundMapperNodelet::onSlamState(const SlamStateConstPtr& msg)
{
  std::lock_guard<std::mutex> lock(mutex_);
  if (!map_switch_.switched(msg->map_index) || !reset_on_map_switch_)
    return;
  // The old map's points sit in another anchoring; mixing them in would double the walls.
  mapper_->reset();
  has_camera_ = false;
  NODELET_INFO("ground_mapper: SLAM map %u, octree and floor start afresh", msg->map_index);
}

bool GroundMapperNodelet::cameraPosition(const ros::Time& stamp, Eigen::Vector3d& position)
{
  std::string error;
  if (lookupOrigin(*tf_buffer_, map_frame_, camera_frame_, stamp, position, &error))
    return true;
  NODELET_WARN_THROTTLE(5.0, "ground_mapper: no TF %s -> %s (%s)", map_frame_.c_str(), camera_frame_.c_str(),
                        error.c_str());
  return false;
}

void GroundMapperNodelet::diagnose(bool ok, const std::string& message)
{
  publishDiagnostics(diag_pub_, "ground_mapper", ok, message,
                     { { "floor_found", mapper_->hasFloor() ? "true" : "false" },
                       { "floor_tilt_deg", mapper_->hasFloor() ? std::to_string(mapper_->floor().plane.tilt_deg) : "nan" },
                       { "obstacle_points", std::to_string(n_obstacles_) },
                       { "points_in_free_space", std::to_string(n_freed_) },
                       { "octree_leaves", std::to_string(mapper_->octree()->numLeafNodes()) },
                       { "clouds_rejected", std::to_string(n_rejected_) },
                       { "last_ms", std::to_string(last_ms_) } });
}

void GroundMapperNodelet::onCloud(const sensor_msgs::PointCloud2ConstPtr& msg)
{
  try
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto start = std::chrono::steady_clock::now();
    if (msg->header.frame_id != map_frame_)
    {
      ++n_rejected_;
      NODELET_ERROR_THROTTLE(5.0, "ground_mapper: cloud in frame '%s', expected '%s'; keeping the last map",
                             msg->header.frame_id.c_str(), map_frame_.c_str());
      diagnose(false, "cloud in an unknown frame");
      return;
    }
    PointList points;
    std::string error;
    if (!cloudToPoints(*msg, points, &error) || points.empty())
    {
      ++n_rejected_;
      NODELET_ERROR_THROTTLE(5.0, "ground_mapper: %s; keeping the last map",
                             error.empty() ? "empty cloud" : error.c_str());
      diagnose(false, error.empty() ? "empty cloud" : error);
      return;
    }
    Eigen::Vector3d camera;
    if (cameraPosition(msg->header.stamp, camera))
    {
      last_camera_ = camera;
      has_camera_ = true;
    }
    if (!has_camera_)
    {
      // Rays need a camera: until the first pose arrives, clouds wait (the last map stays).
      ++n_rejected_;
      diagnose(false, "no camera pose yet (TF " + map_frame_ + " -> " + camera_frame_ + ")");
      return;
    }
    const GroundMapperResult result = mapper_->process(points, { last_camera_ });
    if (!result.ok)
    {
      NODELET_WARN_THROTTLE(10.0, "ground_mapper: no floor found (%s)", result.status.c_str());
      diagnose(false, "no floor yet: " + result.status);
      return;
    }
    if (!result.floor_warning.empty())
      NODELET_WARN_THROTTLE(10.0, "ground_mapper: no floor found (%s); keeping the last floor",
                            result.floor_warning.c_str());
    if (result.octree.n_out_of_range > 0 || !result.octree.origin_ok)
      NODELET_WARN_THROTTLE(5.0, "ground_mapper: %zu points outside the octree's range%s", result.octree.n_out_of_range,
                            result.octree.origin_ok ? "" : ", camera outside it too");
    n_freed_ = result.n_freed;
    n_obstacles_ = result.obstacles.size();
    obstacles_pub_.publish(pointsToCloud(result.obstacles, msg->header));
    floor_points_pub_.publish(pointsToCloud(result.floor_points, msg->header));
    const Eigen::Vector3d n = result.floor.plane.normal;
    const double d = result.floor.plane.d;

    FloorEstimate plane;
    plane.header = msg->header;
    plane.normal.x = n.x();
    plane.normal.y = n.y();
    plane.normal.z = n.z();
    plane.d = d;
    plane.tilt_deg = result.floor.plane.tilt_deg;
    plane.n_inliers = static_cast<std::uint32_t>(result.floor.plane.n_inliers);
    plane.camera_height = n.dot(last_camera_) + d;
    plane_pub_.publish(plane);
    publishMarkers(msg->header);
    last_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    diagnose(true, "ok");
  }
  catch (const std::exception& e)
  {
    NODELET_ERROR_THROTTLE(5.0, "ground_mapper: %s; keeping the last map", e.what());
  }
}

void GroundMapperNodelet::publishMarkers(const std_msgs::Header& header)
{
  if (!last_markers_.isZero() && (header.stamp - last_markers_).toSec() < markers_period_s_)
    return;
  last_markers_ = header.stamp;
  visualization_msgs::Marker floor;
  floor.header = header;
  floor.ns = "floor";
  floor.type = visualization_msgs::Marker::CUBE;
  const FloorPlane& plane = mapper_->floor().plane;
  const Eigen::Vector3d n = plane.normal;
  const Eigen::Vector3d centre = has_camera_ ? last_camera_ - (n.dot(last_camera_) + plane.d) * n
                                             : Eigen::Vector3d(-plane.d * n);
  const Eigen::Quaterniond q = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), n);
  floor.pose.position.x = centre.x();
  floor.pose.position.y = centre.y();
  floor.pose.position.z = centre.z();
  floor.pose.orientation.x = q.x();
  floor.pose.orientation.y = q.y();
  floor.pose.orientation.z = q.z();
  floor.pose.orientation.w = q.w();
  floor.scale.x = floor.scale.y = 6.0;
  floor.scale.z = 0.01;
  floor.color.g = 0.6f;
  floor.color.b = 0.8f;
  floor.color.a = 0.1f;
  floor_marker_pub_.publish(floor);

  visualization_msgs::Marker voxels;
  voxels.header = header;
  voxels.ns = "occupied_voxels";
  voxels.type = visualization_msgs::Marker::CUBE_LIST;
  voxels.pose.orientation.w = 1.0;
  voxels.scale.x = voxels.scale.y = voxels.scale.z = mapper_->config().octree.resolution_m;
  voxels.color.r = 0.3f;
  voxels.color.g = 0.3f;
  voxels.color.b = 1.0f;
  voxels.color.a = 0.6f;
  for (const auto& c : mapper_->octree()->occupiedCenters())
  {
    geometry_msgs::Point p;
    p.x = c.x();
    p.y = c.y();
    p.z = c.z();
    voxels.points.push_back(p);
  }
  visualization_msgs::MarkerArray array;
  array.markers.push_back(voxels);
  voxels_pub_.publish(array);
}

std::string GroundMapperNodelet::mapPath(const std::string& name) const
{
  return map_dir_ + "/" + name + ".bt";
}

bool GroundMapperNodelet::onSave(MapFile::Request& req, MapFile::Response& res)
{
  std::lock_guard<std::mutex> lock(mutex_);
  if (!isValidMapName(req.name))
  {
    res.success = false;
    res.message = "invalid name '" + req.name + "': use 1-64 letters, digits, '_' or '-'";
    return true;
  }
  if (!makeDirectories(map_dir_))
  {
    res.success = false;
    res.message = "cannot create map directory " + map_dir_;
    return true;
  }
  // Written beside the target and renamed over it, so a crash never leaves a half-written map.
  const std::string path = mapPath(req.name);
  const std::string tmp = path + ".tmp";
  const IoStatus status = mapper_->octree()->save(tmp);
  if (!status.ok)
  {
    std::remove(tmp.c_str());
    res.success = false;
    res.message = status.message;
    return true;
  }
  const int fd = ::open(tmp.c_str(), O_RDONLY);
  if (fd >= 0)
  {
    ::fsync(fd);
    ::close(fd);
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0)
  {
    res.success = false;
    res.message = "cannot rename " + tmp + " to " + path;
    return true;
  }
  res.success = true;
  res.message = "saved " + path;
  return true;
}

bool GroundMapperNodelet::onLoad(MapFile::Request& req, MapFile::Response& res)
{
  std::lock_guard<std::mutex> lock(mutex_);
  if (!isValidMapName(req.name))
  {
    res.success = false;
    res.message = "invalid name '" + req.name + "': use 1-64 letters, digits, '_' or '-'";
    return true;
  }
  const IoStatus status = mapper_->octree()->load(mapPath(req.name));
  res.success = status.ok;
  res.message = status.ok ? "loaded " + mapPath(req.name) : status.message + " (the current octree is kept)";
  if (!status.ok)
    NODELET_ERROR("ground_mapper: %s", res.message.c_str());
  return true;
}

bool GroundMapperNodelet::onReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res)
{
  std::lock_guard<std::mutex> lock(mutex_);
  mapper_->reset();
  res.success = true;
  res.message = "octree and floor cleared";
  return true;
}
}  // namespace sparse_nav
