#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>
#include <random>
#include <stdexcept>
#include <vector>

#include "sparse_nav/core/grid_pipeline.h"
#include "sparse_nav/core/ground_mapper.h"
#include "sparse_nav/core/ray_pass_count.h"
#include "synthetic.h"

using sparse_nav::DensityMethod;
using sparse_nav::GridPipeline;
using sparse_nav::GridPipelineConfig;
using sparse_nav::GridPipelineResult;
using sparse_nav::GroundMapper;
using sparse_nav::GroundMapperConfig;
using sparse_nav::GroundMapperResult;
using sparse_nav::PointList;

namespace
{
/// The synthetic room (z-up, floor at z = 0) in a y-down SLAM frame whose origin is the first
/// camera, 1.1 m above the floor at the room centre.
PointList slamRoom(const PointList& room)
{
  const Eigen::Isometry3d shift(Eigen::Translation3d(-2.5, -2.0, -1.1));
  return sparse_nav::transformPoints(room, sparse_nav::test::zUpToYDown() * shift);
}

GroundMapperConfig mapFrameConfig()
{
  GroundMapperConfig cfg;
  cfg.floor.up_axis = Eigen::Vector3d::UnitZ();
  cfg.align_to_floor = false;  // as the ground_mapper nodelet: the input is the z-up map frame
  cfg.keep_floor = false;
  return cfg;
}
}  // namespace

TEST(GroundMapper, BandsAreMeasuredFromTheFloorAndRaysStayInTheBand)
{
  GroundMapper mapper(mapFrameConfig());
  const PointList room = sparse_nav::test::makeRoom();
  const GroundMapperResult r = mapper.process(room, { Eigen::Vector3d(2.5, 2.0, 1.2) });
  ASSERT_TRUE(r.ok) << r.status;
  EXPECT_NEAR(r.floor.plane.tilt_deg, 0.0, 0.5);
  EXPECT_NEAR(r.floor.plane.height(), 0.0, 0.03);
  EXPECT_TRUE(r.to_output.isApprox(Eigen::Isometry3d::Identity()));
  EXPECT_GT(r.n_floor_band, 0u);
  EXPECT_FALSE(r.floor_points.empty());
  EXPECT_EQ(r.obstacles.size() + r.n_freed + r.n_passed + r.n_floor_band + r.n_ceiling_band, room.size());
  for (const auto& p : r.obstacles)
  {
    EXPECT_GE(p.z(), 0.15 - 0.03);
    EXPECT_LE(p.z(), 2.2 + 0.03);
  }
  // A floor point's ray ends where it leaves the band (0.15 m up), short of the point itself.
  EXPECT_EQ(r.rays.size(), room.size());
  ASSERT_NE(mapper.octree(), nullptr);
  EXPECT_GT(r.octree.n_new_voxels, 0u);
  EXPECT_GT(r.octree.n_rays, 0u);
}

TEST(GroundMapper, FreeSpaceFilterDropsAStrayPointInSpaceTheRaysCrossed)
{
  // The density filter would drop the lone stray point first; this is the free-space filter's test.
  GroundMapperConfig config = mapFrameConfig();
  config.density.method = DensityMethod::kNone;
  GroundMapper mapper(config);
  const Eigen::Vector3d camera(2.5, 2.0, 1.2);
  // The SLAM map grows over three updates (new wall points each time); every update's new rays
  // cross the room's interior.
  for (double offset : { 0.0, 0.03, 0.06 })
  {
    PointList room = sparse_nav::test::makeRoom(5.0, 4.0, 0.9, 0.1, 0.005, static_cast<unsigned>(7 + offset * 100));
    for (auto& p : room)
    {
      if (p.z() > 0.2f)
      {
        p.z() += static_cast<float>(offset);
      }
    }
    const GroundMapperResult r = mapper.process(room, { camera });
    ASSERT_TRUE(r.ok) << r.status;
    EXPECT_EQ(r.n_freed, 0u);  // walls are never freed by rays that end on them
  }
  // Then a point appears in the middle of the room (monocular smear into open space).
  PointList room = sparse_nav::test::makeRoom();
  const std::size_t n_room = room.size();
  room.emplace_back(1.5f, 1.0f, 1.1f);
  const GroundMapperResult r = mapper.process(room, { camera });
  ASSERT_TRUE(r.ok) << r.status;
  EXPECT_EQ(r.n_freed, 1u);
  for (const auto& p : r.obstacles)
  {
    EXPECT_FALSE(std::abs(p.x() - 1.5f) < 0.01f && std::abs(p.y() - 1.0f) < 0.01f) << "the stray point was kept";
  }
  EXPECT_GT(r.obstacles.size(), n_room / 2);

  // Without the filter the same point stays.
  GroundMapperConfig cfg = config;
  cfg.free_space_filter = false;
  GroundMapper unfiltered(cfg);
  EXPECT_EQ(unfiltered.process(room, { camera }).n_freed, 0u);
}

namespace
{
bool isObstacle(const GroundMapperResult& r, const Eigen::Vector3f& p)
{
  for (const auto& o : r.obstacles)
  {
    if ((o - p).norm() < 1e-4f)
    {
      return true;
    }
  }
  return false;
}

/// True when the straight line from a to b passes through the box [lo, hi] (sampled finely).
bool crossesBox(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi)
{
  for (int k = 1; k < 400; ++k)
  {
    const Eigen::Vector3d p = a + (b - a) * (k / 400.0);
    if ((p.array() > lo.array()).all() && (p.array() < hi.array()).all())
    {
      return true;
    }
  }
  return false;
}
}  // namespace

TEST(GroundMapper, RaysPassingUnderAStrayPointDropItButRaysOverABoxDoNot)
{
  GroundMapperConfig config = mapFrameConfig();
  config.density.method = DensityMethod::kNone;  // it would take the lone stray point first
  const Eigen::Vector3d camera(2.5, 2.0, 1.2);
  PointList scene = sparse_nav::test::makeRoom();
  // A wall outside, where the camera sees it through the door (x 1.0 to 1.9 m in the wall y = 0).
  PointList outside;
  sparse_nav::test::addWall(outside, -1.0, -1.5, 2.5, -1.5, 0.3, 2.0, 0.1);
  for (const auto& p : outside)
  {
    const double t = camera.y() / (camera.y() - p.y());  // where the ray crosses y = 0
    const double x = camera.x() + t * (p.x() - camera.x());
    if (x > 1.05 && x < 1.85)
    {
      scene.push_back(p);
    }
  }
  // A 0.5 m high box; the camera sees its top and the two faces towards it, not what it hides.
  // Its points sit inside its cells, whose edges rays going past it may graze.
  const Eigen::Vector3d box_lo(3.6, 0.8, 0.0), box_hi(4.0, 1.2, 0.5);
  PointList visible;
  for (const auto& p : scene)
  {
    if (!crossesBox(camera, p.cast<double>(), box_lo, box_hi))
    {
      visible.push_back(p);
    }
  }
  ASSERT_LT(visible.size(), scene.size());
  PointList box;
  sparse_nav::test::addWall(box, 3.625, 0.825, 3.625, 1.175, 0.2, 0.5, 0.05);
  sparse_nav::test::addWall(box, 3.625, 1.175, 3.975, 1.175, 0.2, 0.5, 0.05);
  for (double x = 3.675; x < 4.0; x += 0.1)
  {
    for (double y = 0.825; y < 1.15; y += 0.1)
    {
      box.emplace_back(static_cast<float>(x), static_cast<float>(y), 0.5f);
    }
  }
  visible.insert(visible.end(), box.begin(), box.end());
  // Depth noise put a point into the doorway, at 1 m; rays to the wall outside pass under it.
  const Eigen::Vector3f stray(1.45f, 0.02f, 1.0f);
  visible.push_back(stray);

  GroundMapper mapper(config);
  const GroundMapperResult r = mapper.process(visible, { camera });
  ASSERT_TRUE(r.ok) << r.status;
  EXPECT_FALSE(isObstacle(r, stray)) << r.status;
  EXPECT_GE(r.n_passed, 1u);
  for (const auto& p : box)
  {
    EXPECT_TRUE(isObstacle(r, p)) << "box point " << p.transpose() << " dropped; " << r.status;
  }

  config.clear_hit_min_rays = 0;
  GroundMapper off(config);
  const GroundMapperResult kept = off.process(visible, { camera });
  EXPECT_TRUE(isObstacle(kept, stray));
  EXPECT_EQ(kept.n_passed, 0u);
}

TEST(GroundMapper, RaysNearTheirEndDoNotClearThePointsJustBeforeIt)
{
  // A point 0.1 m in front of the wall x = 5 and wall points right behind it, lower: the rays to
  // them pass under it in its last 4 % (monocular depth noise makes such neighbours).
  GroundMapperConfig config = mapFrameConfig();
  config.density.method = DensityMethod::kNone;
  const Eigen::Vector3d camera(2.5, 2.025, 1.2);
  PointList scene = sparse_nav::test::makeRoom();
  for (double z = 0.6; z < 0.95; z += 0.1)
  {
    scene.emplace_back(5.0f, 2.025f, static_cast<float>(z));
  }
  const Eigen::Vector3f front(4.9f, 2.025f, 1.0f);
  scene.push_back(front);
  GroundMapper mapper(config);
  const GroundMapperResult r = mapper.process(scene, { camera });
  ASSERT_TRUE(r.ok) << r.status;
  EXPECT_TRUE(isObstacle(r, front)) << r.status;

  config.clear_range_margin = 0.0;
  GroundMapper no_margin(config);
  EXPECT_FALSE(isObstacle(no_margin.process(scene, { camera }), front));
}

TEST(GroundMapper, ACloudTooWideForTheRayCountKeepsItsObstaclesAndSaysSo)
{
  GroundMapperConfig config = mapFrameConfig();
  config.density.method = DensityMethod::kNone;
  config.clear_max_cells = 1000;  // the room spans 100 x 80 cells
  const PointList scene = sparse_nav::test::makeRoom();
  const std::size_t n_room = scene.size();
  GroundMapper mapper(config);
  const GroundMapperResult r = mapper.process(scene, { Eigen::Vector3d(2.5, 2.0, 1.2) });
  ASSERT_TRUE(r.ok) << r.status;
  EXPECT_EQ(r.n_passed, 0u);
  EXPECT_NE(r.status.find("not counted"), std::string::npos) << r.status;
  EXPECT_GT(r.obstacles.size(), n_room / 2);
}

TEST(GroundMapper, RayClearingConfigIsValidated)
{
  GroundMapperConfig config;
  config.clear_hit_min_rays = -1;
  EXPECT_THROW(config.validate(), std::invalid_argument);
  config = GroundMapperConfig();
  config.clear_cell_m = 0.0;
  EXPECT_THROW(config.validate(), std::invalid_argument);
  config = GroundMapperConfig();
  config.clear_range_margin = 1.0;
  EXPECT_THROW(config.validate(), std::invalid_argument);
}

TEST(GridPipeline, IncrementalUpdateEqualsAFullRebuildOnTheSamePoints)
{
  const PointList before = slamRoom(sparse_nav::test::makeRoom());
  // 1% of the points, on one wall above the floor band, move by 3 cm (a local bundle adjustment).
  PointList after = before;
  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0.0f, 0.03f);
  std::size_t moved = 0;
  for (auto& p : after)
  {
    // SLAM frame: x right, y down, z forward; the east wall is at x = +2.5, heights above 0.5 m.
    if (moved < before.size() / 100 && p.x() > 2.4f && p.y() < -0.5f + 1.1f - 1.0f)
    {
      p += Eigen::Vector3f(noise(rng), noise(rng), noise(rng));
      ++moved;
    }
  }
  ASSERT_GT(moved, 10u);

  // The incremental pipeline keeps the floor of the first cloud; the full rebuild finds it in the
  // second. Fitting every point (no subsampling) keeps that floor the same, since no floor point moved.
  GridPipelineConfig cfg;
  cfg.ground.floor.max_fit_points = 1000000;
  GridPipeline incremental(cfg);
  const GridPipelineResult first = incremental.process(before, {});
  ASSERT_TRUE(first.ok) << first.status;
  const GridPipelineResult update = incremental.process(after, {});
  ASSERT_TRUE(update.ok) << update.status;
  EXPECT_FALSE(update.grid.full_rebuild);
  EXPECT_LT(update.grid.recomputed_tiles.size(), first.grid.recomputed_tiles.size());
  // Only the moved points' voxels cast rays again.
  EXPECT_LE(update.octree.n_new_voxels, moved);
  EXPECT_GT(first.octree.n_new_voxels, 10 * update.octree.n_new_voxels);

  GridPipeline full(cfg);
  const GridPipelineResult rebuilt = full.process(after, {});
  ASSERT_TRUE(rebuilt.ok) << rebuilt.status;
  EXPECT_TRUE(rebuilt.grid.full_rebuild);
  EXPECT_EQ(update.n_obstacles, rebuilt.n_obstacles);
  EXPECT_TRUE(update.slam_to_map.isApprox(rebuilt.slam_to_map, 1e-12));
  const auto& a = incremental.grid();
  const auto& b = full.grid();
  ASSERT_EQ(a.width, b.width);
  ASSERT_EQ(a.height, b.height);
  EXPECT_DOUBLE_EQ(a.origin_x_m, b.origin_x_m);
  EXPECT_DOUBLE_EQ(a.origin_y_m, b.origin_y_m);
  std::size_t differ = 0;
  for (std::size_t i = 0; i < a.data.size(); ++i)
  {
    differ += a.data[i] != b.data[i] ? 1 : 0;
  }
  EXPECT_EQ(differ, 0u);
}

TEST(GroundMapper, TheFloorIsFoundBeforeTheDensityFilterThinsIt)
{
  // Walls from 0.3 m up, a floor of isolated points 0.6 m apart (monocular floors are sparse) and a lone
  // stray point in the room: the density filter (0.3 m, 5 neighbours) would leave no floor, so
  // the floor is searched first and the filter only thins what goes on to the octree and grid.
  PointList cloud;
  sparse_nav::test::addWall(cloud, 0, 0, 6, 0, 0.3, 2.4, 0.15);
  sparse_nav::test::addWall(cloud, 6, 0, 6, 5, 0.3, 2.4, 0.15);
  sparse_nav::test::addWall(cloud, 6, 5, 0, 5, 0.3, 2.4, 0.15);
  sparse_nav::test::addWall(cloud, 0, 5, 0, 0, 0.3, 2.4, 0.15);
  sparse_nav::test::addFloor(cloud, 0.3, 0.3, 5.7, 4.7, 0.6);
  cloud.emplace_back(3.0f, 2.5f, 1.0f);
  GroundMapper mapper(mapFrameConfig());
  const GroundMapperResult r = mapper.process(cloud, { Eigen::Vector3d(3.0, 2.5, 1.2) });
  ASSERT_TRUE(r.ok) << r.status;
  EXPECT_NEAR(r.floor.plane.height(), 0.0, 0.03);
  EXPECT_NEAR(r.floor.plane.tilt_deg, 0.0, 0.5);
  EXPECT_EQ(r.density.n_in, cloud.size());
  EXPECT_LT(r.density.n_out, cloud.size());
  for (const auto& p : r.obstacles)
  {
    EXPECT_FALSE(std::abs(p.x() - 3.0f) < 0.01f && std::abs(p.y() - 2.5f) < 0.01f) << "the stray point was kept";
  }
  EXPECT_GT(r.stages_ms.count("density"), 0u);
}

namespace
{
/// Counts of a RayPassCount built from nothing on these rays and candidates, at every candidate.
std::vector<std::uint32_t> builtCounts(const std::vector<Eigen::Vector2d>& cam_xy, const std::vector<double>& cam_h,
                                       const std::vector<sparse_nav::PassRay>& rays,
                                       const std::vector<sparse_nav::PassCandidate>& candidates)
{
  sparse_nav::RayPassCount fresh;
  EXPECT_TRUE(fresh.build(cam_xy, cam_h, sparse_nav::PassRaySource::of(rays), candidates));
  std::vector<std::uint32_t> counts;
  for (const auto& c : candidates)
  {
    counts.push_back(fresh.count(c.xy));
  }
  return counts;
}
}  // namespace

TEST(RayPassCount, UpdatesGiveTheCountsOfABuildFromNothing)
{
  // Two cameras in a 6 m x 5 m room of wall points at many heights, and stray points inside;
  // each round some points move or go and new ones come, walls and strays alike.
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const std::vector<Eigen::Vector2d> cam_xy{ { 2.0, 2.5 }, { 4.1, 1.7 } };
  const std::vector<double> cam_h{ 1.2, 0.9 };
  auto randomPoint = [&]() {
    const double t = u(rng);
    Eigen::Vector2d xy;
    if (t < 0.8)
    {
      const double s = u(rng);
      const int wall = static_cast<int>(u(rng) * 4);
      xy = wall == 0 ? Eigen::Vector2d(6.0 * s, 0.0)
           : wall == 1 ? Eigen::Vector2d(6.0, 5.0 * s)
           : wall == 2 ? Eigen::Vector2d(6.0 * s, 5.0)
                       : Eigen::Vector2d(0.0, 5.0 * s);
      xy += Eigen::Vector2d(u(rng) - 0.5, u(rng) - 0.5) * 0.1;
    }
    else
    {
      xy = Eigen::Vector2d(0.3 + 5.4 * u(rng), 0.3 + 4.4 * u(rng));
    }
    return std::make_pair(xy, 0.2 + 2.0 * u(rng));
  };
  std::vector<sparse_nav::PassRay> rays;
  std::vector<sparse_nav::PassCandidate> candidates;
  std::vector<char> is_candidate;
  for (int i = 0; i < 4000; ++i)
  {
    const auto p = randomPoint();
    rays.push_back(sparse_nav::PassRay{ static_cast<std::uint32_t>(i % 2), p.first, p.second });
    is_candidate.push_back(p.second < 1.9 ? 1 : 0);  // the rest: above the band, a ray only
  }
  auto candidatesOf = [&]() {
    std::vector<sparse_nav::PassCandidate> out;
    for (std::size_t i = 0; i < rays.size(); ++i)
    {
      if (is_candidate[i])
      {
        out.push_back(sparse_nav::PassCandidate{ rays[i].end_xy, rays[i].end_h });
      }
    }
    return out;
  };
  candidates = candidatesOf();
  sparse_nav::RayPassCount count;
  ASSERT_TRUE(count.build(cam_xy, cam_h, sparse_nav::PassRaySource::of(rays), candidates));
  for (int round = 0; round < 8; ++round)  // past a quarter of the index stale: it is sorted again
  {
    std::vector<sparse_nav::PassRay> removed_rays, added_rays;
    std::vector<sparse_nav::PassCandidate> removed_candidates, added_candidates;
    for (std::size_t i = 0; i < rays.size(); ++i)
    {
      if (u(rng) < 0.02)
      {
        removed_rays.push_back(rays[i]);
        if (is_candidate[i])
        {
          removed_candidates.push_back(sparse_nav::PassCandidate{ rays[i].end_xy, rays[i].end_h });
        }
        const auto p = randomPoint();
        rays[i] = sparse_nav::PassRay{ rays[i].camera, p.first, p.second };
        is_candidate[i] = p.second < 1.9 ? 1 : 0;
        added_rays.push_back(rays[i]);
        if (is_candidate[i])
        {
          added_candidates.push_back(sparse_nav::PassCandidate{ rays[i].end_xy, rays[i].end_h });
        }
      }
    }
    candidates = candidatesOf();
    ASSERT_TRUE(count.update(cam_xy, cam_h, removed_rays, added_rays, removed_candidates, added_candidates,
                             sparse_nav::PassRaySource::of(rays), candidates));
    EXPECT_FALSE(count.lastWasBuild()) << "round " << round;
    EXPECT_GT(count.numRecounted(), 0u);
    const std::vector<std::uint32_t> expected = builtCounts(cam_xy, cam_h, rays, candidates);
    std::size_t differ = 0, passed = 0;
    for (std::size_t j = 0; j < candidates.size(); ++j)
    {
      differ += count.count(candidates[j].xy) != expected[j] ? 1 : 0;
      passed += expected[j] >= 3 ? 1 : 0;
    }
    EXPECT_EQ(differ, 0u) << "round " << round;
    EXPECT_GT(passed, 10u);  // the strays are seen past: the counts are not all zero
  }
  // A new candidate beyond the counted box is counted by a build.
  const sparse_nav::PassRay far{ 0, Eigen::Vector2d(9.0, 2.0), 1.0 };
  rays.push_back(far);
  candidates.push_back(sparse_nav::PassCandidate{ far.end_xy, far.end_h });
  ASSERT_TRUE(count.update(cam_xy, cam_h, {}, { far }, {}, { candidates.back() }, sparse_nav::PassRaySource::of(rays),
                           candidates));
  EXPECT_TRUE(count.lastWasBuild());
}

TEST(GroundMapper, AnUpdateThroughACorrespondenceGivesWhatAFreshMapperGives)
{
  // A room with stray points inside, seen from two cameras; then some points go, some move and
  // new ones come. The correspondence (which point of the new cloud was which of the old) lets
  // the mapper look at the changed points alone; the result must be a fresh mapper's.
  GroundMapperConfig config = mapFrameConfig();
  config.keep_floor = true;
  config.free_space_filter = false;  // the octree keeps history a fresh mapper has not seen
  std::mt19937 rng(23);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  config.floor.max_fit_points = 1000000;  // every floor point: the same floor in both clouds
  PointList before = sparse_nav::test::makeRoom();
  auto addStrays = [&](PointList& cloud, int n) {
    for (int i = 0; i < n; ++i)  // clusters that the density filter keeps
    {
      const Eigen::Vector3f centre(0.5f + 4.0f * u(rng), 0.5f + 3.0f * u(rng), 0.3f + 1.5f * u(rng));
      for (int k = 0; k < 8; ++k)
      {
        cloud.push_back(centre + Eigen::Vector3f(u(rng), u(rng), u(rng)) * 0.05f);
      }
    }
  };
  addStrays(before, 40);
  const std::vector<Eigen::Vector3d> cameras{ { 2.5, 2.0, 1.2 }, { 1.0, 3.0, 1.0 } };
  PointList after;
  std::vector<std::int32_t> previous_index;
  std::size_t moved = 0, dropped = 0;
  for (std::size_t i = 0; i < before.size(); ++i)
  {
    // Floor points stay: both mappers then find the same floor.
    const float t = before[i].z() > 0.3f ? u(rng) : 1.0f;
    if (t < 0.02f)
    {
      ++dropped;
      continue;
    }
    after.push_back(before[i]);
    previous_index.push_back(static_cast<std::int32_t>(i));
    if (t < 0.05f)
    {
      after.back() += Eigen::Vector3f(u(rng) - 0.5f, u(rng) - 0.5f, u(rng) - 0.5f) * 0.1f;
      previous_index.back() = -1;
      ++moved;
    }
  }
  addStrays(after, 15);
  previous_index.resize(after.size(), -1);
  ASSERT_GT(moved, 10u);
  ASSERT_GT(dropped, 10u);

  GroundMapper incremental(config);
  const GroundMapperResult first = incremental.process(before, cameras);
  ASSERT_TRUE(first.ok) << first.status;
  const GroundMapperResult update = incremental.process(after, cameras, &previous_index);
  ASSERT_TRUE(update.ok) << update.status;
  GroundMapper fresh(config);
  const GroundMapperResult expected = fresh.process(after, cameras);
  ASSERT_TRUE(expected.ok) << expected.status;

  auto sorted = [](PointList points) {
    std::sort(points.begin(), points.end(), [](const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
      return std::tie(a.x(), a.y(), a.z()) < std::tie(b.x(), b.y(), b.z());
    });
    return points;
  };
  EXPECT_EQ(update.n_passed, expected.n_passed);
  EXPECT_GT(expected.n_passed, 20u);  // strays seen past: the count matters here
  EXPECT_EQ(update.density.n_out, expected.density.n_out);
  EXPECT_LT(update.density.n_counted, after.size());
  EXPECT_TRUE(sorted(update.obstacles) == sorted(expected.obstacles));
  // An update lists only the rays that changed; rays() gives all of them, those of a rebuild.
  EXPECT_TRUE(update.incremental);
  EXPECT_TRUE(update.rays.empty());
  const std::vector<sparse_nav::FreeRay> all = incremental.rays();
  ASSERT_EQ(all.size(), expected.rays.size());
  auto key = [](const sparse_nav::FreeRay& r) { return std::make_tuple(r.from.x(), r.from.y(), r.to.x(), r.to.y()); };
  std::vector<std::tuple<double, double, double, double>> a, b;
  for (std::size_t i = 0; i < all.size(); ++i)
  {
    a.push_back(key(all[i]));
    b.push_back(key(expected.rays[i]));
  }
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  EXPECT_TRUE(a == b);
}

TEST(GridPipeline, UpdatesThroughEmptyAndBrokenCloudsStillEndOnTheGridOfARebuild)
{
  // The incremental state must survive clouds that stop the chain early (empty, all NaN) and
  // clouds whose guard drops points mid-list (shifting every later point): whatever came before,
  // the last update gives the grid a rebuild on the last cloud gives.
  const PointList room = slamRoom(sparse_nav::test::makeRoom());
  std::mt19937 rng(41);
  std::normal_distribution<float> noise(0.0f, 0.03f);
  auto moved = [&](PointList cloud, std::size_t every) {
    for (std::size_t i = 0; i < cloud.size(); i += every)
    {
      if (cloud[i].y() < -0.2f)  // above the floor band: the floor stays the same
      {
        cloud[i] += Eigen::Vector3f(noise(rng), noise(rng), noise(rng));
      }
    }
    return cloud;
  };
  const float nan = std::numeric_limits<float>::quiet_NaN();
  PointList with_nans = moved(room, 53);
  with_nans.insert(with_nans.begin() + 100, Eigen::Vector3f(nan, 0.0f, 1.0f));
  with_nans.insert(with_nans.begin() + 2000, Eigen::Vector3f(1e9f, 0.0f, 1.0f));
  const PointList last = moved(room, 37);
  const std::vector<PointList> sequence{ room, PointList(), moved(room, 71), PointList(50, Eigen::Vector3f(nan, nan, nan)),
                                         with_nans, moved(room, 97), last };

  GridPipelineConfig cfg;
  cfg.ground.floor.max_fit_points = 1000000;
  GridPipeline incremental(cfg);
  bool any_incremental = false;
  for (const PointList& cloud : sequence)
  {
    const GridPipelineResult r = incremental.process(cloud, {});
    EXPECT_EQ(r.ok, !cloud.empty() && cloud.front().allFinite()) << r.status;
    any_incremental = any_incremental || (r.ok && !r.grid.full_rebuild);
  }
  EXPECT_TRUE(any_incremental);
  GridPipeline fresh(cfg);
  ASSERT_TRUE(fresh.process(last, {}).ok);
  ASSERT_EQ(incremental.grid().width, fresh.grid().width);
  ASSERT_EQ(incremental.grid().height, fresh.grid().height);
  std::size_t differ = 0;
  for (std::size_t i = 0; i < fresh.grid().data.size(); ++i)
  {
    differ += incremental.grid().data[i] != fresh.grid().data[i] ? 1 : 0;
  }
  EXPECT_EQ(differ, 0u);
}
