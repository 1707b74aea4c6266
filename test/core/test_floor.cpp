#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include "sparse_nav/core/floor_plane.h"
#include "synthetic.h"
#include "../../src/core/kth_smallest.h"

using sparse_nav::FloorDetector;
using sparse_nav::FloorDetectorConfig;
using sparse_nav::FloorResult;
using sparse_nav::PointList;

namespace
{
/// The synthetic room (z-up, floor at z = 0) tilted by `tilt_deg` about the x axis and then
/// expressed in a raw ORB-SLAM-like frame (y down), shifted so the floor is not through the origin.
PointList tiltedRoomYDown(double tilt_deg, Eigen::Isometry3d* room_to_slam = nullptr)
{
  const Eigen::Isometry3d tilt(Eigen::AngleAxisd(tilt_deg * M_PI / 180.0, Eigen::Vector3d::UnitX()));
  const Eigen::Isometry3d shift(Eigen::Translation3d(-2.0, -1.5, -1.1));  // camera 1.1 m above the floor
  const Eigen::Isometry3d t = sparse_nav::test::zUpToYDown() * tilt * shift;
  if (room_to_slam)
  {
    *room_to_slam = t;
  }
  return sparse_nav::transformPoints(sparse_nav::test::makeRoom(), t);
}
}  // namespace

TEST(KthSmallest, AgreesWithNthElementInEveryOrderAndWithRepeats)
{
  std::mt19937 rng(9);
  std::uniform_int_distribution<int> coarse(0, 40);  // many repeated values
  std::normal_distribution<double> fine(0.0, 1.0);
  std::vector<std::vector<double>> inputs;
  for (std::size_t n : { 1u, 2u, 7u, 1000u, 10007u })
  {
    std::vector<double> repeats(n), spread(n);
    for (std::size_t i = 0; i < n; ++i)
    {
      repeats[i] = coarse(rng) * 0.25;
      spread[i] = fine(rng);
    }
    std::vector<double> ascending = spread, descending = spread;
    std::sort(ascending.begin(), ascending.end());
    std::sort(descending.rbegin(), descending.rend());  // every value replaces the heap's top
    inputs.insert(inputs.end(), { repeats, spread, ascending, descending });
  }
  for (const auto& values : inputs)
  {
    for (std::size_t k : { std::size_t{ 0 }, values.size() / 100, values.size() / 3, values.size() - 1 })
    {
      std::vector<double> sorted = values;
      std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(k), sorted.end());
      EXPECT_EQ(sparse_nav::kthSmallest(values, k), sorted[k]) << "n " << values.size() << " k " << k;
    }
  }
}

TEST(FloorDetector, FindsTheFloorForTiltsUpTo15Degrees)
{
  const FloorDetector detector;  // defaults: up (0, -1, 0), 15 deg
  for (double tilt : { 0.0, 3.0, 7.5, 10.0, 14.0, 15.0 })
  {
    const FloorResult r = detector.detect(tiltedRoomYDown(tilt));
    ASSERT_TRUE(r.found) << "tilt " << tilt << ": " << r.reason;
    EXPECT_NEAR(r.plane.tilt_deg, tilt, 0.5) << "tilt " << tilt;
    EXPECT_NEAR(r.plane.height(), -1.1, 0.05) << "tilt " << tilt;  // 1.1 m below the SLAM origin
  }
}

TEST(FloorDetector, NoFloorForA25DegreeTiltAndTheReasonSaysSo)
{
  const FloorResult r = FloorDetector().detect(tiltedRoomYDown(25.0));
  EXPECT_FALSE(r.found);
  EXPECT_NE(r.reason.find("no floor plane within 15.0 deg"), std::string::npos) << r.reason;
  EXPECT_NEAR(r.best_plane_tilt_deg, 25.0, 1.0);
}

TEST(FloorDetector, AFloorTiltedJustBeyondTheLimitWithoutWallsIsReported)
{
  // A dense floor and sparse clutter above it, no walls to tell up: the floor's 21 deg tilt must be
  // reported, not a floor at the edge of the 15 deg cone.
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 6.0f), h(0.3f, 2.5f);
  std::normal_distribution<float> noise(0.0f, 0.01f);
  PointList room;
  for (int i = 0; i < 3000; ++i)
  {
    room.emplace_back(u(rng), u(rng), noise(rng));
  }
  for (int i = 0; i < 800; ++i)
  {
    room.emplace_back(u(rng), u(rng), h(rng));
  }
  const Eigen::Isometry3d tilt(Eigen::AngleAxisd(21.0 * M_PI / 180.0, Eigen::Vector3d::UnitX()));
  const FloorResult r =
      FloorDetector().detect(sparse_nav::transformPoints(room, sparse_nav::test::zUpToYDown() * tilt));
  EXPECT_FALSE(r.found) << "tilt " << r.plane.tilt_deg;
  EXPECT_NE(r.reason.find("no floor plane within 15.0 deg"), std::string::npos) << r.reason;
  EXPECT_NEAR(r.best_plane_tilt_deg, 21.0, 1.5);
}

TEST(FloorDetector, NoFloorInACloudWithoutPlanes)
{
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-5.0f, 5.0f);
  PointList pts(3000);
  for (auto& p : pts)
  {
    p = Eigen::Vector3f(u(rng), u(rng), u(rng));
  }
  const FloorResult r = FloorDetector().detect(pts);
  EXPECT_FALSE(r.found);
  EXPECT_FALSE(r.reason.empty());
}

TEST(FloorDetector, TooFewPoints)
{
  const FloorResult r = FloorDetector().detect(PointList{ { 0, 0, 0 }, { 1, 0, 0 } });
  EXPECT_FALSE(r.found);
  EXPECT_NE(r.reason.find("too few points"), std::string::npos);
}

TEST(FloorDetector, ChoosesTheLowestWellSupportedPlaneNotTheCeiling)
{
  // z-up room with a ceiling denser than the floor.
  PointList pts = sparse_nav::test::makeRoom();
  for (double x = 0.1; x < 4.9; x += 0.05)
  {
    for (double y = 0.1; y < 3.9; y += 0.05)
    {
      pts.emplace_back(static_cast<float>(x), static_cast<float>(y), 2.5f);
    }
  }
  FloorDetectorConfig cfg;
  cfg.up_axis = Eigen::Vector3d::UnitZ();
  const FloorResult r = FloorDetector(cfg).detect(pts);
  ASSERT_TRUE(r.found) << r.reason;
  EXPECT_NEAR(r.plane.height(), 0.0, 0.05);
  EXPECT_NEAR(r.plane.tilt_deg, 0.0, 0.5);
}

TEST(FloorDetector, ConfigValidation)
{
  FloorDetectorConfig cfg;
  cfg.max_tilt_deg = 95;
  EXPECT_THROW(FloorDetector{ cfg }, std::invalid_argument);
  cfg = FloorDetectorConfig();
  cfg.up_axis = Eigen::Vector3d::Zero();
  EXPECT_THROW(cfg.validate(), std::invalid_argument);
  EXPECT_THROW(sparse_nav::axisFromString("up"), std::invalid_argument);
  EXPECT_TRUE(sparse_nav::axisFromString("-y").isApprox(Eigen::Vector3d(0, -1, 0)));
  EXPECT_TRUE(sparse_nav::axisFromString("+z").isApprox(Eigen::Vector3d(0, 0, 1)));
}

TEST(Alignment, PutsTheFloorAtZeroWithZUpAndKeepsTheHeading)
{
  for (double tilt : { 0.0, 8.0, 14.0 })
  {
    Eigen::Isometry3d room_to_slam;
    const PointList slam = tiltedRoomYDown(tilt, &room_to_slam);
    const FloorResult r = FloorDetector().detect(slam);
    ASSERT_TRUE(r.found) << r.reason;
    const Eigen::Isometry3d slam_to_map = sparse_nav::alignToFloor(r.plane);
    const Eigen::Isometry3d room_to_map = slam_to_map * room_to_slam;
    // Floor points (z = 0 in the room) land on z = 0, a wall top (z = 2) at z = +2.
    for (const Eigen::Vector3d& p : { Eigen::Vector3d(0.5, 0.5, 0), Eigen::Vector3d(4.5, 3.5, 0), Eigen::Vector3d(2, 2, 0) })
    {
      EXPECT_NEAR((room_to_map * p).z(), 0.0, 0.02) << "tilt " << tilt;
    }
    EXPECT_NEAR((room_to_map * Eigen::Vector3d(0, 0, 2)).z(), 2.0, 0.03);
    // The map's +z is the plane normal; the rotation is minimal, so the SLAM x axis (which is
    // perpendicular to the tilt axis' effect) stays horizontal and keeps its heading.
    const Eigen::Vector3d x_in_map = slam_to_map.linear() * Eigen::Vector3d::UnitX();
    EXPECT_NEAR(x_in_map.x(), 1.0, 1e-3);
    EXPECT_NEAR((slam_to_map.linear() * r.plane.normal - Eigen::Vector3d::UnitZ()).norm(), 0.0, 1e-9);
    // A rigid transform: determinant +1.
    EXPECT_NEAR(slam_to_map.linear().determinant(), 1.0, 1e-9);
  }
}
