#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include "sparse_nav/core/line_features.h"

using sparse_nav::alignScans;
using sparse_nav::classifyCorner;
using sparse_nav::ScanCorner;
using sparse_nav::cornerDistances;
using sparse_nav::CornerType;
using sparse_nav::LineFeatureConfig;
using sparse_nav::LineFeatureExtractor;
using sparse_nav::PointList;
using sparse_nav::PointList2D;
using sparse_nav::ProcrustesConfig;
using sparse_nav::RangeScan;
using sparse_nav::ScanFeatures;
using sparse_nav::ScanWall;
using Eigen::Vector2d;

namespace
{
constexpr double kDeg = M_PI / 180.0;

struct Seg
{
  Vector2d a, b;
};

/// A scan of the segments seen from the origin: n beams from angle_min, step inc, range noise sigma.
RangeScan castScan(const std::vector<Seg>& segs, int n, double angle_min, double inc, double sigma = 0.0,
                   unsigned seed = 1, double range_max = 30.0)
{
  RangeScan scan;
  scan.angle_min_rad = angle_min;
  scan.angle_increment_rad = inc;
  scan.angle_max_rad = angle_min + (n - 1) * inc;
  scan.range_max_m = range_max;
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma > 0.0 ? sigma : 1.0);
  for (int i = 0; i < n; ++i)
  {
    const double ang = angle_min + i * inc;
    const Vector2d d(std::cos(ang), std::sin(ang));
    double best = std::numeric_limits<double>::infinity();
    for (const auto& s : segs)
    {
      const Vector2d e = s.b - s.a;
      const double den = d.x() * e.y() - d.y() * e.x();
      if (std::abs(den) < 1e-12)
        continue;
      const double t = (s.a.x() * e.y() - s.a.y() * e.x()) / den;
      const double u = (s.a.x() * d.y() - s.a.y() * d.x()) / den;
      if (t > 0.0 && u >= 0.0 && u <= 1.0)
        best = std::min(best, t);
    }
    if (std::isfinite(best) && sigma > 0.0)
      best += noise(rng);
    scan.ranges.push_back(std::isfinite(best) && best <= range_max ? static_cast<float>(best)
                                                                   : std::numeric_limits<float>::infinity());
  }
  return scan;
}

RangeScan fullTurn(const std::vector<Seg>& segs, int n = 360, double sigma = 0.0, unsigned seed = 1)
{
  return castScan(segs, n, -M_PI, 2.0 * M_PI / n, sigma, seed);
}

std::vector<Seg> rectangle(double x0, double y0, double x1, double y1)
{
  return { { { x0, y0 }, { x1, y0 } }, { { x1, y0 }, { x1, y1 } }, { { x1, y1 }, { x0, y1 } }, { { x0, y1 }, { x0, y0 } } };
}

double pointToSegment(const Vector2d& p, const Seg& s)
{
  const Vector2d e = s.b - s.a;
  const double u = std::max(0.0, std::min(1.0, (p - s.a).dot(e) / e.squaredNorm()));
  return (s.a + u * e - p).norm();
}

/// Index of the wall whose both ends lie within tol of segment s, or -1.
int findWall(const ScanFeatures& f, const Seg& s, double tol)
{
  for (std::size_t i = 0; i < f.walls.size(); ++i)
    if (pointToSegment(f.walls[i].start, s) < tol && pointToSegment(f.walls[i].end, s) < tol)
      return static_cast<int>(i);
  return -1;
}
}  // namespace

TEST(RangeScan, CheckNamesWhatIsWrong)
{
  RangeScan ok = fullTurn(rectangle(-2, -2, 2, 2));
  EXPECT_EQ(ok.check(), "");
  EXPECT_TRUE(ok.fullCircle());

  RangeScan empty;
  EXPECT_NE(empty.check().find("no beams"), std::string::npos);

  RangeScan mismatched = ok;
  mismatched.angle_max_rad = 0.5;  // 360 beams of 1 degree cannot end at 0.5 rad
  EXPECT_NE(mismatched.check().find("do not match"), std::string::npos) << mismatched.check();

  RangeScan zero_inc = ok;
  zero_inc.angle_increment_rad = 0.0;
  EXPECT_NE(zero_inc.check().find("increment"), std::string::npos);

  RangeScan nan_angle = ok;
  nan_angle.angle_min_rad = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(nan_angle.check().find("not finite"), std::string::npos);

  RangeScan bad_limits = ok;
  bad_limits.range_max_m = -1.0;
  EXPECT_NE(bad_limits.check().find("range_min/range_max"), std::string::npos);
}

TEST(LineFeatureExtractor, BadScansGiveEmptyFeaturesWithAReason)
{
  const LineFeatureExtractor ex;
  const RangeScan good = fullTurn(rectangle(-2, -2, 2, 2));

  RangeScan empty;
  ScanFeatures f = ex.extract(empty);
  EXPECT_FALSE(f.ok);
  EXPECT_TRUE(f.walls.empty());
  EXPECT_FALSE(f.reason.empty());

  RangeScan all_nan = good;
  for (auto& r : all_nan.ranges)
    r = std::numeric_limits<float>::quiet_NaN();
  f = ex.extract(all_nan);
  EXPECT_FALSE(f.ok);
  EXPECT_TRUE(f.walls.empty());
  EXPECT_NE(f.reason.find("no valid return"), std::string::npos) << f.reason;
  EXPECT_EQ(f.n_ruptures, all_nan.ranges.size());

  RangeScan one = all_nan;
  one.ranges[10] = 2.0f;
  f = ex.extract(one);
  EXPECT_FALSE(f.ok);
  EXPECT_TRUE(f.walls.empty());
  EXPECT_NE(f.reason.find("only 1 valid return"), std::string::npos) << f.reason;

  RangeScan mismatched = good;
  mismatched.ranges.resize(100);
  f = ex.extract(mismatched);
  EXPECT_FALSE(f.ok);
  EXPECT_TRUE(f.walls.empty() && f.doors.empty() && f.corners.empty() && f.corridors.empty());
  EXPECT_NE(f.reason.find("do not match"), std::string::npos) << f.reason;

  RangeScan inf_and_zero = good;
  for (std::size_t i = 0; i < inf_and_zero.ranges.size(); ++i)
    inf_and_zero.ranges[i] = i % 2 ? 0.0f : std::numeric_limits<float>::infinity();
  f = ex.extract(inf_and_zero);
  EXPECT_FALSE(f.ok);
  EXPECT_TRUE(f.walls.empty());
}

TEST(LineFeatureConfig, ValidateRejectsNonsense)
{
  LineFeatureConfig c;
  EXPECT_NO_THROW(c.validate());
  c.door_min_width_m = 1.5;  // above door_max_width_m
  EXPECT_THROW(c.validate(), std::invalid_argument);
  c = LineFeatureConfig();
  c.breakpoint_lambda_deg = 95.0;
  EXPECT_THROW(LineFeatureExtractor{ c }, std::invalid_argument);
}

TEST(Breakpoints, BorgesAldonDistance)
{
  // r sin(dphi) / sin(lambda - dphi) + 3 sigma for r = 2 m, 1 deg, lambda 10 deg, sigma 1 cm.
  EXPECT_NEAR(sparse_nav::breakpointDistance(2.0, 1.0 * kDeg, 10.0 * kDeg, 0.01),
              2.0 * std::sin(1.0 * kDeg) / std::sin(9.0 * kDeg) + 0.03, 1e-12);
  EXPECT_NEAR(sparse_nav::breakpointDistance(2.0, 1.0 * kDeg, 10.0 * kDeg, 0.01), 0.2531, 1e-3);
}

TEST(Breakpoints, AnObjectInFrontOfAWallSplitsIt)
{
  // Wall at x = 3 seen over +-40 deg; a 0.6 m plate at x = 1.5 in front of its middle.
  const RangeScan scan = castScan({ { { 3, -3 }, { 3, 3 } }, { { 1.5, -0.3 }, { 1.5, 0.3 } } }, 81, -40 * kDeg, kDeg);
  const ScanFeatures f = LineFeatureExtractor().extract(scan);
  ASSERT_TRUE(f.ok) << f.reason;
  EXPECT_EQ(f.n_ruptures, 0u);
  EXPECT_EQ(f.n_breakpoints, 2u);  // wall -> plate -> wall
  ASSERT_EQ(f.walls.size(), 3u);
  EXPECT_GE(findWall(f, { { 1.5, -0.3 }, { 1.5, 0.3 } }, 0.02), 0);
}

TEST(Ruptures, ReturnsBeyondMaxRangeAreDropped)
{
  LineFeatureConfig c;
  c.max_range_m = 5.0;
  // The near wall (x = 2) is kept; the far one (x = 8) is beyond max_range_m.
  const RangeScan scan = castScan({ { { 2, -1 }, { 2, 1 } }, { { 8, -10 }, { 8, 10 } } }, 91, -45 * kDeg, kDeg);
  const ScanFeatures f = LineFeatureExtractor(c).extract(scan);
  ASSERT_TRUE(f.ok) << f.reason;
  ASSERT_EQ(f.walls.size(), 1u);
  EXPECT_NEAR(f.walls[0].start.x(), 2.0, 1e-6);
  EXPECT_EQ(f.n_ruptures + f.points.size(), scan.ranges.size());
  std::size_t beyond = 0;
  for (float r : scan.ranges)
    beyond += r > 5.0f;
  EXPECT_EQ(f.n_ruptures, beyond);
  EXPECT_GT(beyond, 30u);
}

TEST(IterativeEndPointFit, SplitsAnLAtItsCorner)
{
  PointList2D pts;
  for (int i = 0; i <= 10; ++i)
    pts.emplace_back(0.1 * i, 0.0);
  for (int i = 1; i <= 10; ++i)
    pts.emplace_back(1.0, 0.1 * i);
  const auto pieces = sparse_nav::iterativeEndPointFit(pts, 0, pts.size(), 0.05);
  ASSERT_EQ(pieces.size(), 2u);
  EXPECT_EQ(pieces[0].first, 0u);
  EXPECT_EQ(pieces[0].second, 10u);  // the corner point (index 10) starts the second piece
  EXPECT_EQ(pieces[1].first, 10u);
  EXPECT_EQ(pieces[1].second, pts.size());
  // A straight line stays whole.
  const auto whole = sparse_nav::iterativeEndPointFit(pts, 0, 10, 0.05);
  ASSERT_EQ(whole.size(), 1u);
}

TEST(FitLine, TotalLeastSquares)
{
  PointList2D pts;
  for (int i = 0; i < 20; ++i)
    pts.emplace_back(0.1 * i, 2.0 + 0.5 * 0.1 * i + (i % 2 ? 0.01 : -0.01));
  const auto fit = sparse_nav::fitLine(pts, 0, pts.size());
  // y = 2 + 0.5 x: normal ~ (-0.5, 1) / |.|, offset 2 / |.| (up to sign).
  const Vector2d n = Vector2d(-0.5, 1.0).normalized();
  EXPECT_NEAR(std::abs(fit.normal.dot(n)), 1.0, 1e-3);
  EXPECT_NEAR(std::abs(fit.offset), 2.0 / Vector2d(-0.5, 1.0).norm(), 0.01);
  EXPECT_NEAR(fit.rms_m, 0.01 / Vector2d(-0.5, 1.0).norm(), 2e-3);
}

TEST(Walls, ARoomGivesFourDirectedWallsAndFourOuterCorners)
{
  const auto room = rectangle(-2, -1.5, 4, 2.5);  // robot at the origin, off centre
  const ScanFeatures f = LineFeatureExtractor().extract(fullTurn(room, 360, 0.005, 7));
  ASSERT_TRUE(f.ok) << f.reason;
  ASSERT_EQ(f.walls.size(), 4u);
  for (const auto& side : room)
  {
    const int w = findWall(f, side, 0.05);
    ASSERT_GE(w, 0) << "side (" << side.a.transpose() << ") - (" << side.b.transpose() << ")";
    const ScanWall& wall = f.walls[w];
    EXPECT_GT(wall.length(), (side.b - side.a).norm() - 0.05);  // ends snapped to the corners
    // Directed: the robot (origin) is on the left.
    const Vector2d d = wall.end - wall.start;
    EXPECT_GT(d.x() * (-wall.start.y()) - d.y() * (-wall.start.x()), 0.0);
  }
  ASSERT_EQ(f.corners.size(), 4u);
  for (const ScanCorner& c : f.corners)
  {
    EXPECT_EQ(c.type, CornerType::kOuter);
    EXPECT_NEAR(c.angle_deg, 90.0, 2.0);
    double best = 1e9;
    for (const auto& side : room)
      best = std::min(best, (c.point - side.a).norm());
    EXPECT_LT(best, 0.05);
  }
  EXPECT_TRUE(f.doors.empty());
}

TEST(Corners, ABoxCornerPointingAtTheRobotIsInner)
{
  // A 1 m box whose corner (2, 1) faces the robot.
  const ScanFeatures f = LineFeatureExtractor().extract(fullTurn(rectangle(2, 1, 3, 2)));
  ASSERT_TRUE(f.ok) << f.reason;
  ASSERT_EQ(f.walls.size(), 2u);
  ASSERT_EQ(f.corners.size(), 1u);
  EXPECT_EQ(f.corners[0].type, CornerType::kInner);
  EXPECT_LT((f.corners[0].point - Vector2d(2, 1)).norm(), 0.03);
  // The first wall ends at the corner and the second starts there.
  EXPECT_EQ(f.walls[f.corners[0].wall_in].end, f.corners[0].point);
  EXPECT_EQ(f.walls[f.corners[0].wall_out].start, f.corners[0].point);
}

TEST(Corners, AHiddenCornerIsPotential)
{
  // Walls x = 2 (y <= 1.3) and y = 2 (x <= 1.4): their lines cross at (2, 2), where nothing is seen.
  const ScanFeatures f = LineFeatureExtractor().extract(fullTurn({ { { 2, -3 }, { 2, 1.3 } }, { { 1.4, 2 }, { -3, 2 } } }));
  ASSERT_TRUE(f.ok) << f.reason;
  ASSERT_EQ(f.walls.size(), 2u);
  ASSERT_EQ(f.corners.size(), 1u);
  EXPECT_EQ(f.corners[0].type, CornerType::kPotential);
  EXPECT_LT((f.corners[0].point - Vector2d(2, 2)).norm(), 0.03);
}

// The six cases of seed 002 §3.1 (p = r-c < r-l, q = r-c < c-l, s = r-l < c-l), with the corner at
// the origin. Inner corner: walls from (-3, 0) and to (0, -3) (the solid in the third quadrant).
TEST(Corners, SeedCaseTable)
{
  const Vector2d c(0, 0);
  struct Case
  {
    Vector2d robot, a, b;
    bool p, q, s;
    CornerType type;
  };
  const std::vector<Case> cases = {
    // convex corner near the robot: T T F -> inner
    { { 1, 1 }, { -3, 0 }, { 0, -3 }, true, true, false, CornerType::kInner },
    // convex corner far from the robot: T F F -> inner
    { { 5, 5 }, { -3, 0 }, { 0, -3 }, true, false, false, CornerType::kInner },
    // room corner, robot close to it: T T T -> outer
    { { 0.2, 0.2 }, { 3, 0 }, { 0, 3 }, true, true, true, CornerType::kOuter },
    // room corner, robot inside the triangle: F T T -> outer
    { { 1, 1 }, { 3, 0 }, { 0, 3 }, false, true, true, CornerType::kOuter },
    // room corner, robot just beyond the missing leg: F F T -> outer
    { { 2, 2 }, { 3, 0 }, { 0, 3 }, false, false, true, CornerType::kOuter },
    // room corner, robot far beyond the missing leg: F F F -> outer
    { { 5, 5 }, { 3, 0 }, { 0, 3 }, false, false, false, CornerType::kOuter },
  };
  for (const auto& k : cases)
  {
    const auto d = cornerDistances(k.robot, c, k.a, k.b);
    EXPECT_EQ(d.robot_corner_m < d.robot_leg_m, k.p) << k.robot.transpose();
    EXPECT_EQ(d.robot_corner_m < d.corner_leg_m, k.q) << k.robot.transpose();
    EXPECT_EQ(d.robot_leg_m < d.corner_leg_m, k.s) << k.robot.transpose();
    EXPECT_EQ(classifyCorner(d), k.type) << k.robot.transpose();
  }
  const auto d = cornerDistances({ 1, 1 }, c, { 3, 0 }, { 0, 3 });
  EXPECT_NEAR(d.robot_corner_m, std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(d.robot_leg_m, 1.0 / std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(d.corner_leg_m, 3.0 / std::sqrt(2.0), 1e-12);
}

TEST(Corners, TypeHoldsAtGrazingViews)
{
  // A box corner seen obliquely along one face: still inner; room corners seen so: outer.
  const ScanFeatures box = LineFeatureExtractor().extract(fullTurn(rectangle(2, -4, 6, -1), 720));
  ASSERT_TRUE(box.ok);
  ASSERT_EQ(box.corners.size(), 1u);
  EXPECT_EQ(box.corners[0].type, CornerType::kInner);
  const ScanFeatures room = LineFeatureExtractor().extract(fullTurn(rectangle(-0.5, -0.5, 8, 1.0), 720));
  ASSERT_TRUE(room.ok);
  for (const auto& c : room.corners)
    EXPECT_EQ(c.type, CornerType::kOuter) << c.point.transpose();
}

TEST(Doors, AGapOfDoorWidthBetweenTwoWallsIsADoor)
{
  // Wall y = 2 with a 0.9 m gap centred at x = 0.5; a far wall at y = 6 behind it.
  const std::vector<Seg> segs = { { { 4, 2 }, { 0.95, 2 } }, { { 0.05, 2 }, { -4, 2 } }, { { 6, 6 }, { -6, 6 } } };
  const ScanFeatures f = LineFeatureExtractor().extract(castScan(segs, 181, 0.0, kDeg, 0.005, 3));
  ASSERT_TRUE(f.ok) << f.reason;
  ASSERT_EQ(f.doors.size(), 1u);
  EXPECT_LT((f.doors[0].center() - Vector2d(0.5, 2)).norm(), 0.05);
  EXPECT_NEAR(f.doors[0].width(), 0.9, 0.06);
  // The jamb lies on the wall's line, at most a beam beyond its last return.
  EXPECT_LT((f.walls[f.doors[0].wall_before].end - f.doors[0].start).norm(), 0.05);
  EXPECT_NEAR(f.doors[0].start.y(), 2.0, 0.02);
}

TEST(Doors, AGapAtTheEndOfARecessIsADoor)
{
  // A 1 m wide passage (x from -0.5 to 0.5, y from 1 to 3) ahead of the robot ends in a 0.9 m
  // door between 5 cm stubs; a wall at y = 6 behind it.
  const std::vector<Seg> segs = { { { 0.5, 1 }, { 0.5, 3 } },   { { 0.5, 3 }, { 0.45, 3 } },
                                  { { -0.45, 3 }, { -0.5, 3 } }, { { -0.5, 3 }, { -0.5, 1 } },
                                  { { 6, 6 }, { -6, 6 } } };
  const ScanFeatures f = LineFeatureExtractor().extract(castScan(segs, 721, 0.0, 0.25 * kDeg));
  ASSERT_TRUE(f.ok) << f.reason;
  ASSERT_EQ(f.doors.size(), 1u);
  EXPECT_LT((f.doors[0].center() - Vector2d(0.0, 3.0)).norm(), 0.1);
  EXPECT_NEAR(f.doors[0].width(), 1.0, 0.1);  // between the side walls' ends
}

TEST(Doors, WrongWidthOrABlockedGapIsNoDoor)
{
  const LineFeatureExtractor ex;
  // 2 m gap: too wide.
  ScanFeatures f = ex.extract(castScan({ { { 4, 2 }, { 1, 2 } }, { { -1, 2 }, { -4, 2 } }, { { 6, 6 }, { -6, 6 } } },
                                       181, 0.0, kDeg));
  ASSERT_TRUE(f.ok);
  EXPECT_TRUE(f.doors.empty());
  // 0.9 m gap with a box standing in front of it.
  f = ex.extract(castScan({ { { 4, 2 }, { 0.95, 2 } },
                            { { 0.05, 2 }, { -4, 2 } },
                            { { 6, 6 }, { -6, 6 } },
                            { { 0.6, 1.2 }, { 0.3, 1.2 } } },
                          181, 0.0, kDeg));
  ASSERT_TRUE(f.ok);
  EXPECT_TRUE(f.doors.empty());
  // The range is configurable: a 2 m gap is a door when doors may be 2.2 m wide.
  LineFeatureConfig wide;
  wide.door_max_width_m = 2.2;
  f = LineFeatureExtractor(wide).extract(
      castScan({ { { 4, 2 }, { 1, 2 } }, { { -1, 2 }, { -4, 2 } }, { { 6, 6 }, { -6, 6 } } }, 181, 0.0, kDeg));
  ASSERT_EQ(f.doors.size(), 1u);
  EXPECT_NEAR(f.doors[0].width(), 2.0, 0.1);
}

TEST(Corridors, TwoFacingWallsFormACorridor)
{
  const ScanFeatures f =
      LineFeatureExtractor().extract(fullTurn({ { { -5, -0.8 }, { 5, -0.8 } }, { { 5, 0.9 }, { -5, 0.9 } } }));
  ASSERT_TRUE(f.ok) << f.reason;
  ASSERT_EQ(f.corridors.size(), 1u);
  EXPECT_NEAR(f.corridors[0].width_m, 1.7, 0.03);
  EXPECT_GT(f.corridors[0].length_m, 5.0);
  EXPECT_EQ(f.corridors[0].side_a.size(), 1u);
  EXPECT_EQ(f.corridors[0].side_b.size(), 1u);
  EXPECT_NEAR(f.corridors[0].axis_start.y(), 0.05, 0.03);
  // One wall alone is no corridor.
  const ScanFeatures g = LineFeatureExtractor().extract(fullTurn({ { { -5, -0.8 }, { 5, -0.8 } } }));
  EXPECT_TRUE(g.corridors.empty());
}

TEST(Merging, AThinPillarDoesNotSplitTheWallBehindIt)
{
  // Wall y = 3; a 4 cm pillar at y = 1 casts a 12 cm shadow on it.
  const ScanFeatures f =
      LineFeatureExtractor().extract(castScan({ { { 4, 3 }, { -4, 3 } }, { { 0.02, 1 }, { -0.02, 1 } } }, 361, 0.0,
                                              0.5 * kDeg));
  ASSERT_TRUE(f.ok) << f.reason;
  ASSERT_EQ(f.walls.size(), 1u);
  EXPECT_GE(findWall(f, { { 4, 3 }, { -4, 3 } }, 0.02), 0);
  EXPECT_GE(f.n_breakpoints, 2u);
}

TEST(Merging, FullTurnSeamDoesNotSplitAWall)
{
  // The wall x = -2 lies behind the robot, across the scan's first and last beams.
  const ScanFeatures f = LineFeatureExtractor().extract(fullTurn({ { { -2, 3 }, { -2, -3 } } }));
  ASSERT_TRUE(f.ok);
  ASSERT_EQ(f.walls.size(), 1u);
  EXPECT_GT(f.walls[0].length(), 5.5);
}

TEST(VirtualScan, NearestPointInTheHeightBandPerBearing)
{
  PointList pts;
  for (double y = -1.0; y <= 1.0; y += 0.05)
    for (double z = 0.0; z <= 2.5; z += 0.25)
      pts.emplace_back(3.0f, static_cast<float>(y), static_cast<float>(z));
  pts.emplace_back(1.0f, 0.0f, 2.4f);   // above the band: ignored
  pts.emplace_back(1.5f, 0.0f, 0.05f);  // below the band: ignored
  pts.emplace_back(std::numeric_limits<float>::quiet_NaN(), 0.0f, 1.0f);
  pts.emplace_back(2.0f, 0.0f, 1.0f);   // in the band, nearer than the wall
  sparse_nav::VirtualScanConfig cfg;
  cfg.n_beams = 360;
  const RangeScan scan = sparse_nav::virtualScan(pts, { 1.0, 0.0, 0.0 }, cfg);
  EXPECT_EQ(scan.check(), "");
  EXPECT_TRUE(scan.fullCircle());
  // Robot at (1, 0) facing +x: bin of bearing 0 is index 180.
  EXPECT_NEAR(scan.ranges[180], 1.0, 1e-5);
  EXPECT_NEAR(scan.ranges[183], 2.0 / std::cos(3 * kDeg), 0.06);
  EXPECT_TRUE(std::isinf(scan.ranges[0]));  // nothing behind
  // Facing +y, the wall is at bearing -90 deg: bin 90.
  const RangeScan turned = sparse_nav::virtualScan(pts, { 1.0, 0.0, M_PI / 2 }, cfg);
  EXPECT_NEAR(turned.ranges[90], 1.0, 1e-5);
  cfg.max_height_m = -1.0;
  EXPECT_THROW(sparse_nav::virtualScan(pts, {}, cfg), std::invalid_argument);
  // A virtual scan of a room cloud gives the room's walls.
  PointList room;
  for (const auto& s : rectangle(-2, -2, 3, 2))
    for (double u = 0.0; u <= 1.0; u += 0.002)
      for (double z = 0.2; z < 1.9; z += 0.4)
      {
        const Vector2d p = s.a + u * (s.b - s.a);
        room.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(z));
      }
  cfg = sparse_nav::VirtualScanConfig();
  const ScanFeatures f = LineFeatureExtractor().extract(sparse_nav::virtualScan(room, { 0.5, 0.0, 0.3 }, cfg));
  ASSERT_TRUE(f.ok) << f.reason;
  EXPECT_EQ(f.walls.size(), 4u);
  EXPECT_EQ(f.corners.size(), 4u);
}

TEST(Procrustes, RecoversAKnownMotion)
{
  const RangeScan scan = fullTurn(rectangle(-2, -1.5, 4, 2.5), 360, 0.0);
  const PointList2D target = sparse_nav::scanPoints(scan, 0.02, 30.0);
  Eigen::Isometry2d truth = Eigen::Isometry2d::Identity();
  truth.rotate(8.0 * kDeg);
  truth.pretranslate(Vector2d(0.25, -0.15));
  PointList2D source;
  for (const auto& p : target)
    source.push_back(truth.inverse() * p);
  const auto r = alignScans(source, target, ProcrustesConfig());
  ASSERT_TRUE(r.ok) << r.reason;
  EXPECT_LT((r.transform.translation() - truth.translation()).norm(), 1e-3);
  EXPECT_NEAR(Eigen::Rotation2Dd(r.transform.linear()).angle(), 8.0 * kDeg, 1e-4);
  EXPECT_GT(r.transform.linear().determinant(), 0.0);
  EXPECT_LT(r.rms_m, 1e-3);
  EXPECT_DOUBLE_EQ(r.inlier_fraction, 1.0);
  // Half of the source moved away: half of it overlaps the target.
  PointList2D half = source;
  for (std::size_t i = 0; i < half.size(); i += 2)
    half[i] += Vector2d(50.0, 50.0);
  const auto h = alignScans(half, target, ProcrustesConfig());
  ASSERT_TRUE(h.ok) << h.reason;
  EXPECT_NEAR(h.inlier_fraction, 0.5, 0.01);
}

TEST(Procrustes, NoReflectionAndBadInput)
{
  PointList2D a, mirrored;
  for (int i = 0; i < 50; ++i)
  {
    a.emplace_back(0.1 * i, 0.02 * i * i);
    mirrored.emplace_back(-0.1 * i, 0.02 * i * i);
  }
  ProcrustesConfig cfg;
  cfg.max_correspondence_m = 10.0;
  const auto r = alignScans(a, mirrored, cfg);
  ASSERT_TRUE(r.ok) << r.reason;
  EXPECT_NEAR(r.transform.linear().determinant(), 1.0, 1e-9);  // a rotation, never a mirror

  const auto few = alignScans(PointList2D(3, Vector2d(1, 1)), a, ProcrustesConfig());
  EXPECT_FALSE(few.ok);
  EXPECT_NE(few.reason.find("too few"), std::string::npos);
  PointList2D nan(50, Vector2d(std::numeric_limits<double>::quiet_NaN(), 0.0));
  EXPECT_FALSE(alignScans(nan, a, ProcrustesConfig()).ok);
  PointList2D far;
  for (const auto& p : a)
    far.push_back(p + Vector2d(100, 100));
  const auto apart = alignScans(far, a, ProcrustesConfig());
  EXPECT_FALSE(apart.ok);
  EXPECT_NE(apart.reason.find("pairs"), std::string::npos);
}

TEST(TransformFeatures, MovesEveryFeature)
{
  ScanFeatures f = LineFeatureExtractor().extract(fullTurn(rectangle(-2, -1.5, 4, 2.5)));
  ASSERT_TRUE(f.ok);
  const Vector2d c0 = f.corners.at(0).point;
  Eigen::Isometry2d t = Eigen::Isometry2d::Identity();
  t.translate(Vector2d(10, 0));
  t.rotate(M_PI / 2);
  sparse_nav::transformFeatures(f, t);
  EXPECT_LT((f.corners[0].point - (t * c0)).norm(), 1e-9);
}
