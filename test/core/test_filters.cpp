#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <tuple>
#include <stdexcept>

#include <pcl/filters/radius_outlier_removal.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include "sparse_nav/core/cloud_filters.h"
#include "synthetic.h"

using sparse_nav::DensityFilter;
using sparse_nav::DensityFilterConfig;
using sparse_nav::DensityMethod;
using sparse_nav::IncrementalVoxelGrid;
using sparse_nav::IncrementalVoxelFilter;
using sparse_nav::PointGuard;
using sparse_nav::PointGuardConfig;
using sparse_nav::PointGuardStats;
using sparse_nav::PointList;
using sparse_nav::VoxelFilter;
using sparse_nav::VoxelFilterConfig;
using sparse_nav::VoxelFilterStats;

TEST(PointGuard, DropsNonFiniteAndFarPointsAndCountsThem)
{
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  PointList in{ { 1, 2, 3 }, { nan, 0, 0 }, { 0, inf, 0 }, { 0, 0, -inf }, { 1e9f, 0, 0 }, { 0, -1e9f, 0 },
                { 9999, -9999, 0 } };
  PointGuardStats stats;
  const PointList out = PointGuard().apply(in, &stats);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(stats.n_in, 7u);
  EXPECT_EQ(stats.n_non_finite, 3u);
  EXPECT_EQ(stats.n_out_of_range, 2u);
  EXPECT_EQ(stats.n_out, 2u);
  EXPECT_FLOAT_EQ(out[0].x(), 1.0f);
  EXPECT_FLOAT_EQ(out[1].x(), 9999.0f);
}

TEST(PointGuard, EmptyCloudGivesEmptyResult)
{
  PointGuardStats stats;
  EXPECT_TRUE(PointGuard().apply(PointList(), &stats).empty());
  EXPECT_EQ(stats.n_in, 0u);
}

TEST(Configs, ValidateRejectsBadValues)
{
  PointGuardConfig g;
  g.max_abs_coordinate = -1;
  EXPECT_THROW(g.validate(), std::invalid_argument);
  DensityFilterConfig d;
  d.radius_m = 0;
  EXPECT_THROW(d.validate(), std::invalid_argument);
  d = DensityFilterConfig();
  d.ipcl_rounds = 0;
  EXPECT_THROW(DensityFilter{ d }, std::invalid_argument);
  VoxelFilterConfig v;
  v.leaf_size_m = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(v.validate(), std::invalid_argument);
  EXPECT_THROW(sparse_nav::densityMethodFromString("median"), std::invalid_argument);
}

namespace
{
/// A dense 1 m x 1 m patch (5 cm spacing) plus isolated points far from it and from each other.
PointList denseWithIsolated(std::size_t* n_dense)
{
  PointList pts;
  for (int i = 0; i < 20; ++i)
  {
    for (int j = 0; j < 20; ++j)
    {
      pts.emplace_back(0.05f * i, 0.05f * j, 0.0f);
    }
  }
  *n_dense = pts.size();
  pts.emplace_back(5.0f, 5.0f, 5.0f);
  pts.emplace_back(-5.0f, 3.0f, 1.0f);
  pts.emplace_back(3.0f, -4.0f, 0.0f);
  return pts;
}
}  // namespace

TEST(DensityFilter, IpclRemovesIsolatedPointsAndKeepsDenseOnes)
{
  std::size_t n_dense = 0;
  const PointList pts = denseWithIsolated(&n_dense);
  DensityFilterConfig cfg;
  cfg.method = DensityMethod::kIpcl;
  cfg.radius_m = 0.06;  // the 4 axis neighbours at 5 cm
  cfg.min_neighbors = 2;
  cfg.ipcl_rounds = 3;
  sparse_nav::DensityFilterStats stats;
  const PointList out = DensityFilter(cfg).apply(pts, &stats);
  EXPECT_EQ(out.size(), n_dense);
  for (const auto& p : out)
  {
    EXPECT_LT(p.norm(), 2.0f);
  }
  EXPECT_GE(stats.rounds_run, 1);
}

TEST(DensityFilter, IpclRoundsApplyRemovalsAtTheEndOfEachRound)
{
  // A chain a-b-c with 1 m spacing and k = 2: in round 1 only b has 2 neighbours; a and c go at
  // the end of the round; in round 2 b has none left and goes too.
  PointList chain{ { 0, 0, 0 }, { 1, 0, 0 }, { 2, 0, 0 } };
  DensityFilterConfig cfg;
  cfg.method = DensityMethod::kIpcl;
  cfg.radius_m = 1.01;
  cfg.min_neighbors = 2;
  cfg.ipcl_rounds = 1;
  PointList one = DensityFilter(cfg).apply(chain);
  ASSERT_EQ(one.size(), 1u);
  EXPECT_FLOAT_EQ(one[0].x(), 1.0f);
  cfg.ipcl_rounds = 2;
  EXPECT_TRUE(DensityFilter(cfg).apply(chain).empty());
}

TEST(DensityFilter, RadiusOutlierMatchesIpclOneRound)
{
  std::size_t n_dense = 0;
  const PointList pts = denseWithIsolated(&n_dense);
  DensityFilterConfig cfg;
  cfg.method = DensityMethod::kRadiusOutlier;
  cfg.radius_m = 0.06;
  cfg.min_neighbors = 3;
  const PointList ror = DensityFilter(cfg).apply(pts);
  cfg.method = DensityMethod::kIpcl;
  cfg.ipcl_rounds = 1;
  const PointList ipcl = DensityFilter(cfg).apply(pts);
  EXPECT_EQ(ror.size(), ipcl.size());
  // Corners of the patch have only 2 neighbours within 6 cm.
  EXPECT_EQ(ror.size(), n_dense - 4);
}

namespace
{
// The points PCL's RadiusOutlierRemoval keeps at the filter's radius and neighbour count.
PointList pclRadiusOutlierKept(const PointList& pts, const DensityFilterConfig& cfg)
{
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  for (const auto& p : pts)
  {
    cloud->points.emplace_back(p.x(), p.y(), p.z());
  }
  cloud->width = static_cast<std::uint32_t>(cloud->points.size());
  cloud->height = 1;
  pcl::RadiusOutlierRemoval<pcl::PointXYZ> ror;
  ror.setInputCloud(cloud);
  ror.setRadiusSearch(cfg.radius_m);
  ror.setMinNeighborsInRadius(cfg.min_neighbors);
  pcl::PointCloud<pcl::PointXYZ> kept;
  ror.filter(kept);
  PointList out;
  for (const auto& p : kept.points)
  {
    out.emplace_back(p.x, p.y, p.z);
  }
  return out;
}
}  // namespace

TEST(DensityFilter, RadiusOutlierKeepsExactlyWhatPclKeeps)
{
  // A noisy room plus scattered outliers, filtered at the nodelet's defaults (0.3 m, 5 neighbours).
  PointList pts = sparse_nav::test::makeRoom(5.0, 4.0, 0.9, 0.25, 0.02, 11);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-2.0f, 7.0f);
  for (int i = 0; i < 400; ++i)
  {
    pts.emplace_back(u(rng), u(rng), u(rng) * 0.4f);
  }
  const DensityFilterConfig cfg;
  ASSERT_EQ(cfg.method, DensityMethod::kRadiusOutlier);
  const PointList ours = DensityFilter(cfg).apply(pts);

  const PointList kept = pclRadiusOutlierKept(pts, cfg);
  ASSERT_EQ(ours.size(), kept.size());
  EXPECT_LT(ours.size(), pts.size());  // some outliers went
  for (std::size_t i = 0; i < ours.size(); ++i)
  {
    EXPECT_EQ(ours[i], kept[i]) << i;
  }
}

TEST(DensityFilter, RadiusOutlierMatchesPclOnClustersSpreadOverThousandsOfMetres)
{
  // Small clusters, some straddling cell boundaries, at far and negative coordinates: tens of
  // thousands of occupied cells, so the filter's cell lookups probe past other cells' keys.
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> centre(-5000.0f, 5000.0f);
  std::uniform_real_distribution<float> offset(-0.1f, 0.1f);
  std::uniform_int_distribution<int> size(1, 9);
  PointList pts;
  for (int c = 0; c < 6000; ++c)
  {
    const Eigen::Vector3f at(centre(rng), centre(rng), 0.3f * std::round(centre(rng) / 1000.0f));
    for (int n = size(rng); n > 0; --n)
    {
      pts.push_back(at + Eigen::Vector3f(offset(rng), offset(rng), offset(rng)));
    }
  }
  const DensityFilterConfig cfg;
  const PointList ours = DensityFilter(cfg).apply(pts);

  const PointList kept = pclRadiusOutlierKept(pts, cfg);
  ASSERT_EQ(ours.size(), kept.size());
  EXPECT_GT(ours.size(), pts.size() / 3);  // clusters of 6 or more points stay, smaller ones go
  EXPECT_LT(ours.size(), 3 * pts.size() / 4);
  for (std::size_t i = 0; i < ours.size(); ++i)
  {
    EXPECT_EQ(ours[i], kept[i]) << i;
  }
}

TEST(DensityFilter, RadiusOutlierMatchesPclInASmallBoxOfCells)
{
  // Uniform points in a 1.5 m cube at about the neighbour count's density: the filter indexes
  // its cells densely over the box, and a third of the cells lie on the box's faces.
  std::mt19937 rng(23);
  std::uniform_real_distribution<float> u(-0.7f, 0.8f);
  PointList pts;
  for (int i = 0; i < 170; ++i)
  {
    pts.emplace_back(u(rng), u(rng), u(rng));
  }
  const DensityFilterConfig cfg;
  const PointList ours = DensityFilter(cfg).apply(pts);
  const PointList kept = pclRadiusOutlierKept(pts, cfg);
  ASSERT_EQ(ours.size(), kept.size());
  EXPECT_GT(ours.size(), pts.size() / 10);
  EXPECT_LT(ours.size(), 9 * pts.size() / 10);
  for (std::size_t i = 0; i < ours.size(); ++i)
  {
    EXPECT_EQ(ours[i], kept[i]) << i;
  }
}

TEST(DensityFilter, IpclOnAHundredThousandPointsKeepsClustersAndDropsStrays)
{
  // Sparse background, a dense cluster, and strays far from everything: at this size the filter
  // must still decide each point by its own neighbourhood (speed is measured in bench/).
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.0f, 10.0f);
  std::uniform_real_distribution<float> c(0.0f, 0.1f);
  PointList pts(100000);
  for (auto& p : pts)
  {
    p = Eigen::Vector3f(u(rng), u(rng), u(rng) * 0.3f);
  }
  const std::size_t cluster_begin = pts.size();
  for (int i = 0; i < 500; ++i)
  {
    pts.emplace_back(20.0f + c(rng), 20.0f + c(rng), c(rng));
  }
  for (int i = 0; i < 10; ++i)
  {
    pts.emplace_back(50.0f + 5.0f * i, -30.0f, 0.0f);
  }
  DensityFilterConfig cfg;
  cfg.method = DensityMethod::kIpcl;
  cfg.radius_m = 0.1;
  cfg.min_neighbors = 3;
  const PointList out = DensityFilter(cfg).apply(pts);
  std::size_t in_cluster = 0, strays = 0;
  for (const auto& p : out)
  {
    in_cluster += p.x() >= 20.0f && p.x() <= 20.1f && p.y() >= 20.0f ? 1 : 0;
    strays += p.x() >= 50.0f ? 1 : 0;
  }
  EXPECT_EQ(in_cluster, pts.size() - cluster_begin - 10);
  EXPECT_EQ(strays, 0u);
  EXPECT_LT(out.size(), pts.size() - 10);  // the sparse background thins out too
}

namespace
{
/// The points in voxel order (z, then y, then x), as a voxel filter from nothing gives them.
PointList sortedPoints(PointList points, double leaf = 0.05)
{
  auto key = [leaf](const Eigen::Vector3f& p) {
    return std::make_tuple(std::floor(p.z() / leaf), std::floor(p.y() / leaf), std::floor(p.x() / leaf));
  };
  std::sort(points.begin(), points.end(), [&](const Eigen::Vector3f& a, const Eigen::Vector3f& b) { return key(a) < key(b); });
  return points;
}
/// n points uniform in 6 m x 6 m x 0.6 m around the origin, drawn from rng.
PointList randomSlab(std::size_t n, std::mt19937& rng)
{
  std::uniform_real_distribution<float> u(-3.0f, 3.0f);
  PointList points(n);
  for (auto& p : points)
  {
    p = Eigen::Vector3f(u(rng), u(rng), u(rng) * 0.1f);
  }
  return points;
}
}  // namespace

TEST(VoxelFilter, AveragesPointsPerVoxel)
{
  PointList pts{ { 1.01f, 0.01f, 0.01f }, { 0.01f, 0.01f, 0.01f }, { 0.03f, 0.03f, 0.03f } };
  VoxelFilterConfig cfg;
  cfg.leaf_size_m = 0.1;
  VoxelFilterStats stats;
  const PointList out = VoxelFilter(cfg).apply(pts, &stats);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(stats.n_in, 3u);
  EXPECT_EQ(stats.n_out, 2u);
  // Sorted by voxel index, x last: the voxel at x = 0 comes first.
  EXPECT_TRUE(out[0].isApprox(Eigen::Vector3f(0.02f, 0.02f, 0.02f), 1e-6f)) << out[0].transpose();
  EXPECT_TRUE(out[1].isApprox(pts[0], 1e-6f));
}

TEST(VoxelFilter, HugeExtentKeepsEveryVoxel)
{
  // 1e6 m in every axis with a 1 cm leaf: 1e24 voxels, far beyond an int32 voxel index (PCL
  // returned such clouds unfiltered) and beyond 21 bits per axis (the packed sort key).
  PointList pts;
  for (int i = 0; i < 50; ++i)
  {
    const float c = static_cast<float>(i) * 2.0e4f;
    pts.emplace_back(c, c, c);
    pts.emplace_back(c + 0.001f, c, c);  // same voxel as the previous point
  }
  pts.emplace_back(1.0e6f, 1.0e6f, 1.0e6f);
  VoxelFilterConfig cfg;
  cfg.leaf_size_m = 0.01;
  VoxelFilterStats stats;
  const PointList out = VoxelFilter(cfg).apply(pts, &stats);
  EXPECT_EQ(stats.n_in, pts.size());
  EXPECT_EQ(out.size(), 51u);  // pairs merged, nothing returned raw
  EXPECT_TRUE(std::is_sorted(out.begin(), out.end(), [](const Eigen::Vector3f& a, const Eigen::Vector3f& b) { return a.z() < b.z(); }));
}

TEST(VoxelFilter, CentroidsAreTheMeansOfTheVoxelsInVoxelOrder)
{
  // Points on both sides of zero, several per voxel: each centroid is its voxel's mean (sums in
  // double), voxels sorted by z, then y, then x index.
  std::mt19937 rng(5);
  PointList pts = randomSlab(20000, rng);
  const PointList half(pts.begin(), pts.begin() + 10000);
  pts.insert(pts.end(), half.begin(), half.end());
  const double leaf = 0.05, inv = 1.0 / leaf;
  std::map<std::tuple<double, double, double>, std::pair<Eigen::Vector3d, int>> voxels;
  for (const auto& p : pts)
  {
    const Eigen::Vector3d q = p.cast<double>();
    auto& v = voxels.emplace(std::make_tuple(std::floor(q.z() * inv), std::floor(q.y() * inv), std::floor(q.x() * inv)),
                             std::make_pair(Eigen::Vector3d::Zero(), 0))
                  .first->second;
    v.first += q;
    ++v.second;
  }
  PointList expected;
  for (const auto& kv : voxels)
  {
    expected.push_back((kv.second.first / kv.second.second).cast<float>());
  }
  VoxelFilterConfig cfg;
  cfg.leaf_size_m = leaf;
  EXPECT_TRUE(VoxelFilter(cfg).apply(pts) == expected);
}

TEST(IncrementalVoxelGrid, AnUpdateGivesTheCentroidsOfABuildFromScratch)
{
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-3.0f, 3.0f);
  const PointList before = randomSlab(20000, rng);
  PointList after = before, added, removed;
  std::normal_distribution<float> noise(0.0f, 0.03f);
  for (std::size_t i = 0; i < after.size(); i += 50)
  {
    removed.push_back(after[i]);
    after[i] += Eigen::Vector3f(noise(rng), noise(rng), noise(rng));
    added.push_back(after[i]);
  }
  for (int k = 0; k < 100; ++k)
  {
    after.emplace_back(u(rng) + 10.0f, u(rng), 0.0f);  // new voxels beyond the old ones
    added.push_back(after.back());
  }
  VoxelFilterConfig cfg;
  IncrementalVoxelGrid grid(cfg);
  grid.update(before, {});
  const PointList first = grid.centroids();
  EXPECT_TRUE(first == VoxelFilter(cfg).apply(before));  // from nothing: PCL's order
  grid.update(added, removed);
  const PointList scratch = VoxelFilter(cfg).apply(after);
  ASSERT_EQ(grid.centroids().size(), scratch.size());
  // Bit for bit, the double sums being exact; an update keeps its own order.
  EXPECT_TRUE(sortedPoints(grid.centroids()) == scratch);
  std::size_t same = 0;
  for (std::size_t i = 0; i < scratch.size(); ++i)
  {
    const std::int32_t prev = grid.previousIndex()[i];
    if (prev >= 0)
    {
      ASSERT_EQ(first[static_cast<std::size_t>(prev)], grid.centroids()[i]);
      ++same;
    }
  }
  EXPECT_GT(same, scratch.size() / 2);
  EXPECT_LT(same, scratch.size());
  EXPECT_GT(grid.numDropped(), 0u);
  EXPECT_EQ(grid.numUnknownRemovals(), 0u);
}

TEST(IncrementalVoxelGrid, ManyUpdatesThatEmptyAndFillVoxelsKeepTheCentroidsOfABuildFromScratch)
{
  // Sparse points (about one per voxel): moving them empties voxels and fills new ones, round
  // after round, past the point where the voxel index is made again.
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> u(0.0f, 2.0f);
  PointList cloud(3000);
  for (auto& p : cloud)
  {
    p = Eigen::Vector3f(u(rng), u(rng), u(rng));
  }
  VoxelFilterConfig cfg;
  IncrementalVoxelGrid grid(cfg);
  grid.update(cloud, {});
  for (int round = 0; round < 12; ++round)
  {
    const PointList last = grid.centroids();
    PointList added, removed;
    for (std::size_t i = round % 7; i < cloud.size(); i += 7)
    {
      removed.push_back(cloud[i]);
      cloud[i] = Eigen::Vector3f(u(rng), u(rng), u(rng));
      added.push_back(cloud[i]);
    }
    grid.update(added, removed);
    ASSERT_TRUE(sortedPoints(grid.centroids()) == VoxelFilter(cfg).apply(cloud)) << "round " << round;
    ASSERT_EQ(grid.previousIndex().size(), grid.centroids().size());
    for (std::size_t i = 0; i < grid.centroids().size(); ++i)
    {
      const std::int32_t prev = grid.previousIndex()[i];
      ASSERT_TRUE(prev < 0 || last[static_cast<std::size_t>(prev)] == grid.centroids()[i]) << "round " << round;
    }
  }
}

TEST(DensityFilter, AnUpdateCountsOnlyAroundTheChangedPointsAndKeepsWhatACountOfAllKeeps)
{
  // Clusters of a few points each, so that moving points flips their neighbours' flags.
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 8.0f);
  std::normal_distribution<float> spread(0.0f, 0.15f);
  PointList before;
  for (int c = 0; c < 400; ++c)
  {
    const Eigen::Vector3f centre(u(rng), u(rng), u(rng) * 0.25f);
    const int n = 3 + c % 6;
    for (int k = 0; k < n; ++k)
    {
      before.push_back(centre + Eigen::Vector3f(spread(rng), spread(rng), spread(rng)));
    }
  }
  // The changed cloud: the first 40 points move into the corner region, 30 more appear there, and
  // the points of the corner cluster are dropped; the rest keep their place.
  PointList after;
  std::vector<std::int32_t> previous_index;
  for (std::size_t i = 0; i < before.size(); ++i)
  {
    if (before[i].x() < 1.0f && before[i].y() < 1.0f)
    {
      continue;
    }
    if (i < 40)
    {
      after.push_back(Eigen::Vector3f(u(rng) * 0.2f, u(rng) * 0.2f, 0.5f));
      previous_index.push_back(-1);
    }
    else
    {
      after.push_back(before[i]);
      previous_index.push_back(static_cast<std::int32_t>(i));
    }
  }
  for (int k = 0; k < 30; ++k)
  {
    after.push_back(Eigen::Vector3f(u(rng) * 0.2f, u(rng) * 0.2f, 0.5f));
    previous_index.push_back(-1);
  }
  const DensityFilter filter;
  const std::vector<char> previous_keep = filter.keepFlags(before);
  sparse_nav::DensityFilterStats full_stats, update_stats;
  const std::vector<char> full = filter.keepFlags(after, &full_stats);
  const std::vector<char> updated = filter.keepFlagsUpdated(after, previous_index, before, previous_keep, &update_stats);
  ASSERT_EQ(updated.size(), full.size());
  EXPECT_TRUE(updated == full);
  EXPECT_EQ(update_stats.n_out, full_stats.n_out);
  EXPECT_LT(update_stats.n_counted, after.size() / 2);
  EXPECT_GT(update_stats.n_counted, 0u);
  // A list that is not a correspondence (one previous point claimed twice) is counted whole.
  std::vector<std::int32_t> twice = previous_index;
  twice[1] = twice[0] = 100;
  sparse_nav::DensityFilterStats whole;
  EXPECT_TRUE(filter.keepFlagsUpdated(after, twice, before, previous_keep, &whole) == full);
  EXPECT_EQ(whole.n_counted, after.size());
}

TEST(IncrementalVoxelFilter, ACloudThatMovedInAFewPlacesIsUpdatedThereAndMostlyChangedIsRebuilt)
{
  std::mt19937 rng(12);
  std::uniform_real_distribution<float> u(-3.0f, 3.0f);
  const PointList before = randomSlab(5000, rng);
  VoxelFilterConfig cfg;
  IncrementalVoxelFilter filter(cfg);
  const PointList first = filter.apply(before);
  EXPECT_TRUE(first == VoxelFilter(cfg).apply(before));
  EXPECT_TRUE(filter.rebuilt());
  EXPECT_EQ(filter.numChanged(), before.size());

  // 100 points move and 20 are appended: an update in place.
  PointList after = before;
  for (std::size_t i = 0; i < after.size(); i += 50)
  {
    after[i] += Eigen::Vector3f(0.2f, -0.1f, 0.0f);
  }
  for (int k = 0; k < 20; ++k)
  {
    after.emplace_back(u(rng) + 10.0f, u(rng), 0.0f);
  }
  const PointList second = filter.apply(after);
  EXPECT_FALSE(filter.rebuilt());
  EXPECT_EQ(filter.numChanged(), 120u);
  EXPECT_TRUE(sortedPoints(second) == VoxelFilter(cfg).apply(after));
  std::size_t same = 0;
  for (std::size_t i = 0; i < second.size(); ++i)
  {
    const std::int32_t prev = filter.previousIndex()[i];
    if (prev >= 0)
    {
      ASSERT_EQ(first[static_cast<std::size_t>(prev)], second[i]);
      ++same;
    }
  }
  EXPECT_GT(same, second.size() / 2);

  // The same cloud again: nothing changed, every centroid is the one before.
  const PointList third = filter.apply(after);
  EXPECT_EQ(filter.numChanged(), 0u);
  ASSERT_EQ(third.size(), second.size());
  for (std::size_t i = 0; i < third.size(); ++i)
  {
    EXPECT_EQ(filter.previousIndex()[i], static_cast<std::int32_t>(i));
  }

  // Every point moved (a new SLAM map): built from scratch, in voxel order, nothing kept.
  PointList shifted = after;
  for (auto& p : shifted)
  {
    p += Eigen::Vector3f(0.5f, 0.0f, 0.0f);
  }
  const PointList fourth = filter.apply(shifted);
  EXPECT_TRUE(filter.rebuilt());
  EXPECT_TRUE(fourth == VoxelFilter(cfg).apply(shifted));
  for (const std::int32_t prev : filter.previousIndex())
  {
    EXPECT_EQ(prev, -1);
  }

  // After clear() the next cloud is new even if it is the last one.
  filter.clear();
  EXPECT_TRUE(filter.apply(shifted) == fourth);
  EXPECT_TRUE(filter.rebuilt());
}

TEST(IncrementalVoxelFilter, DisabledItPassesTheCloudOnAndSaysWhichPointsStayed)
{
  IncrementalVoxelFilter filter(VoxelFilterConfig(), false);
  PointList cloud{ { 0.0f, 0.0f, 0.0f }, { 1.0f, 0.0f, 0.0f }, { 2.0f, 0.0f, 0.0f }, { 3.0f, 0.0f, 0.0f } };
  EXPECT_TRUE(filter.apply(cloud) == cloud);
  cloud[1].x() = 1.5f;
  EXPECT_TRUE(filter.apply(cloud) == cloud);
  EXPECT_EQ(filter.numChanged(), 1u);
  EXPECT_EQ(filter.previousIndex(), (std::vector<std::int32_t>{ 0, -1, 2, 3 }));
  EXPECT_TRUE(filter.apply(PointList()).empty());
}

TEST(IncrementalVoxelGrid, RemovingPointsItNeverHeldIsCountedAndIgnored)
{
  IncrementalVoxelGrid grid;
  grid.update({ { 0.01f, 0.01f, 0.01f } }, {});
  grid.update({}, { { 5.0f, 5.0f, 5.0f }, { 0.02f, 0.02f, 0.02f }, { 0.03f, 0.01f, 0.01f } });
  EXPECT_EQ(grid.numUnknownRemovals(), 3u);
  ASSERT_EQ(grid.centroids().size(), 1u);
  EXPECT_TRUE(grid.centroids()[0].isApprox(Eigen::Vector3f(0.01f, 0.01f, 0.01f)));
  grid.update({}, { { 0.01f, 0.01f, 0.01f } });
  EXPECT_TRUE(grid.centroids().empty());
  EXPECT_EQ(grid.numDropped(), 1u);
}

TEST(VoxelFilter, EmptyCloud)
{
  VoxelFilterStats stats;
  EXPECT_TRUE(VoxelFilter().apply(PointList(), &stats).empty());
  EXPECT_EQ(stats.n_out, 0u);
}
