// PCL BoundaryEstimation on a point file, for validation/quality/holes/measure_boundary.py.
// Input: binary float64 file of N x 6 (x y z nx ny nz); prints one 0/1 flag per line.
// Usage: pcl_boundary POINTS.bin RADIUS [ANGLE_RAD=pi/2]
// PCL's defaults: angle criterion only, boundary when the largest gap exceeds pi/2.
#include <pcl/features/boundary.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <vector>

int main(int argc, char** argv) {
    if (argc < 3) {
        std::cerr << "usage: pcl_boundary POINTS.bin RADIUS [ANGLE_RAD]\n";
        return 2;
    }
    std::ifstream in(argv[1], std::ios::binary);
    std::vector<double> v;
    double x;
    while (in.read(reinterpret_cast<char*>(&x), sizeof x)) v.push_back(x);
    if (v.empty() || v.size() % 6) {
        std::cerr << "pcl_boundary: " << argv[1] << ": not an N x 6 float64 file\n";
        return 1;
    }
    const double radius = std::atof(argv[2]);
    const double angle = argc > 3 ? std::atof(argv[3]) : M_PI / 2;
    pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
    pcl::PointCloud<pcl::Normal>::Ptr normals(new pcl::PointCloud<pcl::Normal>);
    for (std::size_t i = 0; i < v.size(); i += 6) {
        cloud->push_back(pcl::PointXYZ(v[i], v[i + 1], v[i + 2]));
        normals->push_back(pcl::Normal(v[i + 3], v[i + 4], v[i + 5]));
    }
    pcl::BoundaryEstimation<pcl::PointXYZ, pcl::Normal, pcl::Boundary> est;
    est.setInputCloud(cloud);
    est.setInputNormals(normals);
    est.setSearchMethod(
        pcl::search::KdTree<pcl::PointXYZ>::Ptr(new pcl::search::KdTree<pcl::PointXYZ>));
    est.setRadiusSearch(radius);
    est.setAngleThreshold(angle);
    pcl::PointCloud<pcl::Boundary> flags;
    est.compute(flags);
    std::string out;
    out.reserve(flags.size() * 2);
    for (const auto& f : flags) {
        out += f.boundary_point ? '1' : '0';
        out += '\n';
    }
    std::fwrite(out.data(), 1, out.size(), stdout);
    return 0;
}
