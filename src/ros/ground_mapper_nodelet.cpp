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
  std::string up_axis = "z";
  loadParam(pnh, "up_axis", up_axis);
  floor_config_.up_axis = axisFromString(up_axis);
  loadParam(pnh, "max_tilt_deg", floor_config_.max_tilt_deg);
  loadParam(pnh, "floor_distance_threshold_m", floor_config_.distance_threshold_m);
  loadParam(pnh, "floor_min_inliers", floor_config_.min_inliers);
  loadParam(pnh, "floor_max_planes", floor_config_.max_planes);
  loadParam(pnh, "floor_clearance_m", floor_clearance_m_);
  loadParam(pnh, "ceiling_height_m", ceiling_height_m_);
  loadParam(pnh, "octree_resolution_m", octree_config_.resolution_m);
  loadParam(pnh, "octree_max_range_m", octree_config_.max_range_m);
  loadParam(pnh, "map_frame", map_frame_);
  loadParam(pnh, "camera_frame", camera_frame_);
  const char* home = std::getenv("HOME");
  map_dir_ = std::string(home ? home : "/tmp") + "/.ros/sparse_nav/maps";
  loadParam(pnh, "map_dir", map_dir_);
  if (map_dir_.rfind("~/", 0) == 0)
    map_dir_ = std::string(home ? home : "/tmp") + map_dir_.substr(1);
  loadParam(pnh, "markers_period_s", markers_period_s_);
  floor_config_.validate();
  octree_config_.validate();
  if (!(ceiling_height_m_ > floor_clearance_m_))
    throw std::invalid_argument("ceiling_height_m must be above floor_clearance_m");

  octree_.reset(new OctreeMap(octree_config_));
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
                     { { "floor_found", has_floor_ ? "true" : "false" },
                       { "floor_tilt_deg", has_floor_ ? std::to_string(floor_.plane.tilt_deg) : "nan" },
                       { "obstacle_points", std::to_string(n_obstacles_) },
                       { "points_in_free_space", std::to_string(n_freed_) },
                       { "octree_leaves", std::to_string(octree_->numLeafNodes()) },
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
    const FloorResult floor = FloorDetector(floor_config_).detect(points);
    if (floor.found)
    {
      floor_ = floor;
      has_floor_ = true;
    }
    else
    {
      NODELET_WARN_THROTTLE(10.0, "ground_mapper: no floor found (%s)%s", floor.reason.c_str(),
                            has_floor_ ? "; keeping the last floor" : "");
    }
    Eigen::Vector3d camera;
    if (cameraPosition(msg->header.stamp, camera))
    {
      last_camera_ = camera;
      has_camera_ = true;
    }
    if (!has_floor_)
    {
      diagnose(false, "no floor yet: " + floor.reason);
      return;
    }
    // Heights are measured from the floor plane, so a slightly tilted or offset map still slices right.
    const Eigen::Vector3d n = floor_.plane.normal;
    const double d = floor_.plane.d;
    // Every update casts rays from the current camera to all points: monocular depth noise smears
    // points into openings (a doorway collects the smear of the room seen through it), and the
    // rays through such an opening outvote those stray hits in the octree.
    if (has_camera_)
    {
      const OctreeInsertStats stats = octree_->insert(points, last_camera_);
      if (stats.n_out_of_range > 0 || !stats.origin_ok)
        NODELET_WARN_THROTTLE(5.0, "ground_mapper: %zu points outside the octree's range%s", stats.n_out_of_range,
                              stats.origin_ok ? "" : ", camera outside it too");
    }
    PointList obstacles, floor_points;
    std::size_t n_freed = 0;
    for (const auto& p : points)
    {
      const double h = n.dot(p.cast<double>()) + d;
      if (h < floor_clearance_m_)
      {
        if (h > -floor_clearance_m_)
          floor_points.push_back(p);
      }
      else if (h <= ceiling_height_m_)
      {
        if (octree_->query(p.cast<double>()) == VoxelState::kFree)
          ++n_freed;
        else
          obstacles.push_back(p);
      }
    }
    n_freed_ = n_freed;
    n_obstacles_ = obstacles.size();
    obstacles_pub_.publish(pointsToCloud(obstacles, msg->header));
    floor_points_pub_.publish(pointsToCloud(floor_points, msg->header));

    FloorEstimate plane;
    plane.header = msg->header;
    plane.normal.x = n.x();
    plane.normal.y = n.y();
    plane.normal.z = n.z();
    plane.d = d;
    plane.tilt_deg = floor_.plane.tilt_deg;
    plane.n_inliers = static_cast<std::uint32_t>(floor_.plane.n_inliers);
    plane.camera_height = has_camera_ ? n.dot(last_camera_) + d : std::nan("");
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
  const Eigen::Vector3d n = floor_.plane.normal;
  const Eigen::Vector3d centre = has_camera_ ? last_camera_ - (n.dot(last_camera_) + floor_.plane.d) * n
                                             : Eigen::Vector3d(-floor_.plane.d * n);
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
  voxels.scale.x = voxels.scale.y = voxels.scale.z = octree_config_.resolution_m;
  voxels.color.r = 0.3f;
  voxels.color.g = 0.3f;
  voxels.color.b = 1.0f;
  voxels.color.a = 0.6f;
  for (const auto& c : octree_->occupiedCenters())
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
  const IoStatus status = octree_->save(tmp);
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
  const IoStatus status = octree_->load(mapPath(req.name));
  res.success = status.ok;
  res.message = status.ok ? "loaded " + mapPath(req.name) : status.message + " (the current octree is kept)";
  if (!status.ok)
    NODELET_ERROR("ground_mapper: %s", res.message.c_str());
  return true;
}

bool GroundMapperNodelet::onReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res)
{
  std::lock_guard<std::mutex> lock(mutex_);
  octree_->clear();
  has_floor_ = false;
  res.success = true;
  res.message = "octree and floor cleared";
  return true;
}
}  // namespace sparse_nav
