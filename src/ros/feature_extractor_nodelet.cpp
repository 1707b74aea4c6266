#include "sparse_nav/ros/feature_extractor_nodelet.h"

#include <chrono>
#include <cmath>
#include <exception>

#include <visualization_msgs/MarkerArray.h>

#include "sparse_nav/ros/conversions.h"
#include "sparse_nav/ros/node_utils.h"

namespace sparse_nav
{
namespace
{
geometry_msgs::Point toPoint(const Eigen::Vector2d& p, double z = 0.0)
{
  geometry_msgs::Point q;
  q.x = p.x();
  q.y = p.y();
  q.z = z;
  return q;
}

std_msgs::ColorRGBA color(float r, float g, float b)
{
  std_msgs::ColorRGBA c;
  c.r = r;
  c.g = g;
  c.b = b;
  c.a = 1.0f;
  return c;
}
}  // namespace

void FeatureExtractorNodelet::onInit()
{
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  loadParam(pnh, "input", input_);
  loadParam(pnh, "map_frame", map_frame_);
  loadParam(pnh, "base_frame", base_frame_);
  loadParam(pnh, "n_beams", virtual_config_.n_beams);
  loadParam(pnh, "min_height_m", virtual_config_.min_height_m);
  loadParam(pnh, "max_height_m", virtual_config_.max_height_m);
  loadParam(pnh, "virtual_range_min_m", virtual_config_.range_min_m);
  loadParam(pnh, "virtual_range_max_m", virtual_config_.range_max_m);
  loadParam(pnh, "min_range_m", config_.min_range_m);
  loadParam(pnh, "max_range_m", config_.max_range_m);
  loadParam(pnh, "breakpoint_lambda_deg", config_.breakpoint_lambda_deg);
  loadParam(pnh, "breakpoint_sigma_m", config_.breakpoint_sigma_m);
  loadParam(pnh, "split_distance_m", config_.split_distance_m);
  loadParam(pnh, "min_segment_points", config_.min_segment_points);
  loadParam(pnh, "min_wall_length_m", config_.min_wall_length_m);
  loadParam(pnh, "merge_angle_deg", config_.merge_angle_deg);
  loadParam(pnh, "merge_gap_m", config_.merge_gap_m);
  loadParam(pnh, "door_min_width_m", config_.door_min_width_m);
  loadParam(pnh, "door_max_width_m", config_.door_max_width_m);
  loadParam(pnh, "door_max_angle_deg", config_.door_max_angle_deg);
  loadParam(pnh, "door_max_offset_m", config_.door_max_offset_m);
  loadParam(pnh, "door_clearance_m", config_.door_clearance_m);
  loadParam(pnh, "corner_min_angle_deg", config_.corner_min_angle_deg);
  loadParam(pnh, "corner_max_gap_m", config_.corner_max_gap_m);
  loadParam(pnh, "corner_potential_gap_m", config_.corner_potential_gap_m);
  loadParam(pnh, "corridor_min_width_m", config_.corridor_min_width_m);
  loadParam(pnh, "corridor_max_width_m", config_.corridor_max_width_m);
  loadParam(pnh, "corridor_min_length_m", config_.corridor_min_length_m);
  loadParam(pnh, "corridor_max_angle_deg", config_.corridor_max_angle_deg);
  loadParam(pnh, "corridor_line_offset_m", config_.corridor_line_offset_m);
  if (input_ != "cloud" && input_ != "scan")
    throw std::invalid_argument("feature_extractor: input must be 'cloud' or 'scan', got '" + input_ + "'");
  virtual_config_.validate();
  extractor_.reset(new LineFeatureExtractor(config_));  // validates config_

  features_pub_ = nh.advertise<sparse_nav::Features>("features", 5);
  markers_pub_ = nh.advertise<visualization_msgs::MarkerArray>("features/markers", 1, true);
  diag_pub_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 5);
  if (input_ == "cloud")
  {
    tf_buffer_.reset(new tf2_ros::Buffer(ros::Duration(30.0)));
    tf_listener_.reset(new tf2_ros::TransformListener(*tf_buffer_, nh));
    sub_ = nh.subscribe("cloud/obstacles", 2, &FeatureExtractorNodelet::onCloud, this);
  }
  else
  {
    sub_ = nh.subscribe("scan", 5, &FeatureExtractorNodelet::onScan, this);
  }
}

void FeatureExtractorNodelet::diagnose(bool ok, const std::string& message)
{
  publishDiagnostics(diag_pub_, "feature_extractor", ok, message,
                     { { "input", input_ },
                       { "walls", std::to_string(n_walls_) },
                       { "doors", std::to_string(n_doors_) },
                       { "corners", std::to_string(n_corners_) },
                       { "corridors", std::to_string(n_corridors_) },
                       { "inputs_refused", std::to_string(n_refused_) },
                       { "last_ms", std::to_string(last_ms_) } });
}

void FeatureExtractorNodelet::refuse(const std_msgs::Header& header, const std::string& reason)
{
  ++n_refused_;
  NODELET_ERROR_THROTTLE(5.0, "feature_extractor: %s; keeping the last features", reason.c_str());
  sparse_nav::FeaturesPtr msg(new sparse_nav::Features);
  msg->header = header;
  msg->ok = false;
  msg->status = reason;
  features_pub_.publish(msg);
  diagnose(false, reason);
}

void FeatureExtractorNodelet::onCloud(const sensor_msgs::PointCloud2ConstPtr& msg)
{
  try
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto start = std::chrono::steady_clock::now();
    if (msg->header.frame_id != map_frame_)
    {
      refuse(msg->header, "cloud in frame '" + msg->header.frame_id + "', expected '" + map_frame_ + "'");
      return;
    }
    PointList points;
    std::string error;
    if (!cloudToPoints(*msg, points, &error))
    {
      refuse(msg->header, error);
      return;
    }
    Pose2D pose;
    try
    {
      const ros::Time when =
          tf_buffer_->canTransform(map_frame_, base_frame_, msg->header.stamp, ros::Duration(0.05)) ? msg->header.stamp
                                                                                                   : ros::Time(0);
      const auto t = tf_buffer_->lookupTransform(map_frame_, base_frame_, when).transform;
      const auto& q = t.rotation;
      pose.x_m = t.translation.x;
      pose.y_m = t.translation.y;
      pose.yaw_rad = std::atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z));
    }
    catch (const tf2::TransformException& e)
    {
      refuse(msg->header, "no TF " + map_frame_ + " -> " + base_frame_ + " (" + e.what() + ")");
      return;
    }
    if (!std::isfinite(pose.x_m) || !std::isfinite(pose.y_m) || !std::isfinite(pose.yaw_rad))
    {
      refuse(msg->header, "robot pose is not finite");
      return;
    }
    ScanFeatures features = extractor_->extract(virtualScan(points, pose, virtual_config_));
    Eigen::Isometry2d to_map = Eigen::Isometry2d::Identity();
    to_map.translate(Eigen::Vector2d(pose.x_m, pose.y_m));
    to_map.rotate(pose.yaw_rad);
    transformFeatures(features, to_map);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    publish(features, msg->header, pose, ms);
  }
  catch (const std::exception& e)
  {
    NODELET_ERROR_THROTTLE(5.0, "feature_extractor: %s", e.what());
  }
}

void FeatureExtractorNodelet::onScan(const sensor_msgs::LaserScanConstPtr& msg)
{
  try
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto start = std::chrono::steady_clock::now();
    if (msg->header.frame_id.empty())
    {
      refuse(msg->header, "scan without a frame_id");
      return;
    }
    RangeScan scan;
    scan.angle_min_rad = msg->angle_min;
    scan.angle_max_rad = msg->angle_max;
    scan.angle_increment_rad = msg->angle_increment;
    scan.range_min_m = msg->range_min;
    scan.range_max_m = msg->range_max;
    scan.ranges = msg->ranges;
    const std::string problem = scan.check();
    if (!problem.empty())
    {
      refuse(msg->header, problem);
      return;
    }
    const ScanFeatures features = extractor_->extract(scan);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    publish(features, msg->header, Pose2D(), ms);
  }
  catch (const std::exception& e)
  {
    NODELET_ERROR_THROTTLE(5.0, "feature_extractor: %s", e.what());
  }
}

void FeatureExtractorNodelet::publish(const ScanFeatures& f, const std_msgs::Header& header, const Pose2D& robot,
                                      double ms)
{
  last_ms_ = ms;
  if (!f.ok)
  {
    refuse(header, f.reason);
    return;
  }
  sparse_nav::FeaturesPtr msg(new sparse_nav::Features);
  msg->header = header;
  msg->ok = true;
  msg->status = "ok";
  msg->robot.x = robot.x_m;
  msg->robot.y = robot.y_m;
  msg->robot.theta = robot.yaw_rad;
  for (const auto& w : f.walls)
  {
    sparse_nav::Wall m;
    m.start = toPoint(w.start);
    m.end = toPoint(w.end);
    m.n_points = static_cast<std::uint32_t>(w.n_points);
    m.rms_m = static_cast<float>(w.rms_m);
    msg->walls.push_back(m);
  }
  for (const auto& d : f.doors)
  {
    sparse_nav::Door m;
    m.start = toPoint(d.start);
    m.end = toPoint(d.end);
    m.center = toPoint(d.center());
    m.width_m = static_cast<float>(d.width());
    m.wall_before = static_cast<std::uint32_t>(d.wall_before);
    m.wall_after = static_cast<std::uint32_t>(d.wall_after);
    msg->doors.push_back(m);
  }
  for (const auto& c : f.corners)
  {
    sparse_nav::Corner m;
    m.type = static_cast<std::uint8_t>(c.type);
    m.point = toPoint(c.point);
    m.wall_in = static_cast<std::uint32_t>(c.wall_in);
    m.wall_out = static_cast<std::uint32_t>(c.wall_out);
    m.angle_deg = static_cast<float>(c.angle_deg);
    m.robot_corner_m = static_cast<float>(c.distances.robot_corner_m);
    m.robot_leg_m = static_cast<float>(c.distances.robot_leg_m);
    m.corner_leg_m = static_cast<float>(c.distances.corner_leg_m);
    msg->corners.push_back(m);
  }
  for (const auto& c : f.corridors)
  {
    sparse_nav::Corridor m;
    m.side_a.assign(c.side_a.begin(), c.side_a.end());
    m.side_b.assign(c.side_b.begin(), c.side_b.end());
    m.width_m = static_cast<float>(c.width_m);
    m.length_m = static_cast<float>(c.length_m);
    m.axis_start = toPoint(c.axis_start);
    m.axis_end = toPoint(c.axis_end);
    msg->corridors.push_back(m);
  }
  n_walls_ = f.walls.size();
  n_doors_ = f.doors.size();
  n_corners_ = f.corners.size();
  n_corridors_ = f.corridors.size();
  features_pub_.publish(msg);
  publishMarkers(f, header);
  diagnose(true, "ok");
}

void FeatureExtractorNodelet::publishMarkers(const ScanFeatures& f, const std_msgs::Header& header)
{
  visualization_msgs::MarkerArray array;
  auto base = [&header](const std::string& ns, int type, double scale) {
    visualization_msgs::Marker m;
    m.header = header;
    m.ns = ns;
    m.id = 0;
    m.type = type;
    m.action = visualization_msgs::Marker::ADD;
    m.pose.orientation.w = 1.0;
    m.scale.x = m.scale.y = m.scale.z = scale;
    return m;
  };
  // Walls sit a little above the floor so the occupancy grid does not hide them.
  constexpr double kZ = 0.05;
  visualization_msgs::Marker walls = base("walls", visualization_msgs::Marker::LINE_LIST, 0.05);
  walls.color = color(0.1f, 0.4f, 1.0f);
  for (const auto& w : f.walls)
  {
    walls.points.push_back(toPoint(w.start, kZ));
    walls.points.push_back(toPoint(w.end, kZ));
  }
  visualization_msgs::Marker doors = base("doors", visualization_msgs::Marker::LINE_LIST, 0.08);
  doors.color = color(0.1f, 0.9f, 0.2f);
  for (const auto& d : f.doors)
  {
    doors.points.push_back(toPoint(d.start, kZ));
    doors.points.push_back(toPoint(d.end, kZ));
  }
  visualization_msgs::Marker corners = base("corners", visualization_msgs::Marker::SPHERE_LIST, 0.15);
  corners.color = color(1.0f, 1.0f, 1.0f);
  for (const auto& c : f.corners)
  {
    corners.points.push_back(toPoint(c.point, kZ));
    // inner: orange, outer: purple, potential: grey
    corners.colors.push_back(c.type == CornerType::kInner   ? color(1.0f, 0.5f, 0.0f)
                             : c.type == CornerType::kOuter ? color(0.6f, 0.2f, 0.9f)
                                                            : color(0.6f, 0.6f, 0.6f));
  }
  visualization_msgs::Marker corridors = base("corridors", visualization_msgs::Marker::LINE_LIST, 0.03);
  corridors.color = color(1.0f, 0.9f, 0.1f);
  for (const auto& c : f.corridors)
  {
    corridors.points.push_back(toPoint(c.axis_start, kZ));
    corridors.points.push_back(toPoint(c.axis_end, kZ));
  }
  // rviz rejects an empty LINE_LIST/SPHERE_LIST as ADD; delete it instead.
  for (auto* m : { &walls, &doors, &corners, &corridors })
  {
    if (m->points.empty())
      m->action = visualization_msgs::Marker::DELETE;
    array.markers.push_back(*m);
  }
  markers_pub_.publish(array);
}
}  // namespace sparse_nav
