#include "bright_clusters.hpp"

#include <algorithm>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>
// The clustering template is instantiated here from its implementation header: the precompiled
// libpcl_segmentation drags in features, filters and ml, 0.12 s at every program start.
#include <pcl/segmentation/extract_clusters.h>
#include <pcl/segmentation/impl/extract_clusters.hpp>

namespace ignav::registration::detail {

std::vector<std::vector<std::size_t>> euclideanClusters(const std::vector<Eigen::Vector3f>& points,
                                                        double tolerance_mm) {
  std::vector<std::vector<std::size_t>> clusters;
  if (points.empty()) return clusters;
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  cloud->reserve(points.size());
  for (const auto& p : points)
    cloud->push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
  pcl::search::KdTree<pcl::PointXYZ>::Ptr tree(new pcl::search::KdTree<pcl::PointXYZ>);
  tree->setInputCloud(cloud);
  std::vector<pcl::PointIndices> found;
  pcl::EuclideanClusterExtraction<pcl::PointXYZ> extraction;
  extraction.setClusterTolerance(tolerance_mm);
  extraction.setMinClusterSize(1);
  extraction.setMaxClusterSize(static_cast<int>(points.size()));
  extraction.setSearchMethod(tree);
  extraction.setInputCloud(cloud);
  extraction.extract(found);
  clusters.reserve(found.size());
  for (const auto& c : found) {
    clusters.emplace_back(c.indices.begin(), c.indices.end());
  }
  std::stable_sort(clusters.begin(), clusters.end(),
                   [](const auto& a, const auto& b) { return a.size() > b.size(); });
  return clusters;
}

}  // namespace ignav::registration::detail
